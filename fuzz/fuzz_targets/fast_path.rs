//! The ASIC-style split against the core alone (issue 11 item 5): byte 0 bit 0 chooses the
//! schedule ([`Mode::Sync`]: the core catches up after every telegram, every answer must
//! be equal byte for byte; [`Mode::Lag`]: the core stays behind in the not-ready window,
//! where a Slave_Diag may only be the older staged diagnosis with Station_Not_Ready set),
//! bit 1 how the split's line gets the telegrams (0: whole, `FastPath::on_frame`; 1: through
//! the streaming seam `phy::stream::TelegramSink` in random pieces — bits 2..4 + 1 bytes
//! after byte 0 give the piece sizes, cycled, from single bytes to 40), the rest is the
//! operation sequence of `pbcard::fast::check` (two masters and a third
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
    let Some((&head, ops)) = data.split_first() else { return };
    let mode = if head & 1 == 0 { Mode::Sync } else { Mode::Lag };
    let (cuts, ops) =
        if head & 2 == 0 { (&[][..], ops) } else { ops.split_at((usize::from(head >> 2 & 7) + 1).min(ops.len())) };
    let r = if cuts.is_empty() { check::run(ops, mode, 2000) } else { check::run_in_pieces(ops, mode, 2000, cuts) };
    if let Err(m) = r {
        panic!("{mode:?} {cuts:02x?}: {m:02x?}");
    }
});
