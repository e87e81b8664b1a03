//! The ASIC-style split against the core alone (issue 11 item 5): byte 0 bit 0 chooses the
//! schedule ([`Mode::Sync`]: the core catches up after every telegram, every answer must
//! be equal byte for byte; [`Mode::Lag`]: the core stays behind in the not-ready window,
//! where a Slave_Diag may only be the older staged diagnosis with Station_Not_Ready set),
//! the rest is the operation sequence of `pbcard::fast::check` (two masters and a third
//! requester, Set_Prm in many forms, Chk_Cfg, Data_Exchange of any length, Slave_Diag,
//! Get_Cfg, Rd_Inp / Rd_Outp, Global_Control, Set_Slave_Add, FDL_Status, SDA, DP-V1 —
//! MSAC_C1 read / write / poll, MSAC_C2 RM / Initiate / transport / Idle / Abort / poll, the
//! DP-V1 task — retries, other stations' traffic, mangled sources, raw bytes, time,
//! application changes). Any difference outside the documented windows (the not-ready
//! diagnosis; a DP-V1 poll answered "not ready" whose response the next poll delivers)
//! panics with both answers.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::fast::check::{self, Mode};

fuzz_target!(|data: &[u8]| {
    let Some((&mode, ops)) = data.split_first() else { return };
    let mode = if mode & 1 == 0 { Mode::Sync } else { Mode::Lag };
    if let Err(m) = check::run(ops, mode, 2000) {
        panic!("{mode:?}: {m:02x?}");
    }
});
