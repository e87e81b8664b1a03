//! What this card is, as the PLC sees it: the constants that the GSD file (`gsd/ODCP0F11.gsd`)
//! declares and the firmware enforces. `host-tests/tests/gsd.rs` parses the GSD with
//! `gsd-parser` and asserts that every value here equals the GSD's — change both together.
//!
//! The DP slave takes them as [`SLAVE`], this product's [`dp::SlaveConfig`], with
//! [`OperateModePolicy`], its Chk_Cfg rule; the composition passes `&card::SLAVE` to
//! [`dp::DpSlave::new`].

use crate::dp;
use crate::time::Baudrate;

/// PROFIBUS ident number (GSD `Ident_Number`, Set_Prm bytes 4–5, diagnosis octets 5–6).
///
/// **Placeholder**: 0x0F11 is *not* registered with PROFIBUS International. A product must
/// obtain its own number from PI and change it here and in the GSD file name.
pub const IDENT_NUMBER: u16 = 0x0F11;

/// Default station address after a factory reset (reference §3.9: 126 is the commissioning
/// address used by Set_Slave_Add).
pub const DEFAULT_ADDRESS: u8 = 126;

/// Highest station address a DP slave may have (127 is broadcast; 126 is the default).
pub const MAX_STATION_ADDRESS: u8 = crate::fdl::telegram::MAX_STATION_ADDRESS;

/// The worst **finish** of any request the fast path answers, in instructions: measured by
/// `qemu_bench` on the QEMU build (its `worst fast path: N instructions` line — the USART1
/// handler for the request's last character, from its entry to the first response byte:
/// the status and data register reads, the clock, `Framer::cut`, `TelegramSink::bytes` of
/// that character and `FastPath::finish`; `qemu_bench` fails when a run exceeds this). Since
/// issue 11's streaming receive it does not grow with the telegram's length: the checksum,
/// the copy into the core's queue slot and the likely answer are done while the bytes arrive;
/// the DP-V1 answers (RM PDU, ready frames, Abort PDUs, SC / RS / RR) are decided and built at
/// the header too, and since session 10 the whole decision with them (`fast::Lean`: every
/// staged service but Set_Slave_Add), so `finish` checks the FCS and the end delimiter and
/// commits it. Measured 427 in session 13 (an MSAC_C1 poll → DS_Read.res; Data_Exchange ≤ 380,
/// Slave_Diag ≤ 388, Set_Prm / Chk_Cfg ≤ 384, FDL_Status ≤ 420; 445 – 447 in session 12; 666 before the lean finish, 1152 before
/// the DP-V1 answers were prepared), with an allowance of ≈ 5 % for the run-to-run spread
/// (`bash scripts/qemu.sh bench`). MaxTsdr_1.5M is 17 for any budget from 465 to 507.
pub const LINE_BUDGET_INSTRUCTIONS: u32 = 470;

/// The streaming receive's cost per character, in instructions: `Framer::cut` and
/// `TelegramSink::bytes` of one character of a long Data_Exchange after its header, measured by
/// `qemu_bench` (its `per-character streaming cost` line; `qemu_bench` fails when a run
/// exceeds this). The per-character receive's work while a request arrives; the DMA mode's
/// remainder at IDLE is measured itself ([`DMA_FINISH_INSTRUCTIONS`]). Measured 80 (branch
/// `tsdr`; 91 before; 83 on main), with an allowance of ≈ 5 %.
pub const STREAM_CHAR_INSTRUCTIONS: u32 = 88;

/// The worst **finish in the DMA mode** (≥ 3 Mbit/s) of any request the fast path answers, in
/// instructions: measured by `qemu_bench --dma` on the `bench-dma` build, which emulates the
/// F411's DMA receive on QEMU (`bsp::qemu::DmaEmu`: the characters reach the fast path in
/// 16-byte chunks as the ring's half/full-transfer interrupts hand them over, the rest at the
/// telegram's end; its `worst DMA-mode finish: N instructions` line, from the IDLE
/// interrupt's entry to the first response byte: the remainder of 1 … 16 characters through
/// `Stream::piece` into the sink, `FastPath::finish`, the answer staged; `qemu_bench --dma`
/// fails when a run exceeds this). Replaces the earlier charge of 15 single characters'
/// cost ([`STREAM_CHAR_INSTRUCTIONS`] each) for the remainder. Measured 1312 in session 13, 1290 – 1300 before (an MSAC_C2
/// poll, 11 bytes: a short request that arrives entirely after the last chunk, so the sink's
/// `begin`, its header in one piece (`Stream::piece` hands a whole header over at once) and
/// the general decision — nothing could be prepared — run at IDLE; the same request with its
/// header in an earlier chunk: ≈ 400 with the lean finish; 1844 before session 10), with an
/// allowance of ≈ 5 %.
pub const DMA_FINISH_INSTRUCTIONS: u32 = 1365;

/// The F411's IDLE handler's own work before and around the fast path in the DMA mode, which
/// QEMU does not execute (no DMA, no IDLE flag): SR, the receive gate, TIM5, NDTR, the T_SYN
/// compare armed, the ring walk (`DmaLine::walk_ring`, `RingWalker::walk`) and the line's own
/// copy of the remainder for the rate control (`Tee`, ≈ 2 a byte): ≈ 130 + 2 × [`DMA_CHUNK`],
/// **estimated** from `crates/bsp/src/f411.rs` (README "Board budget"), not measured.
pub const F411_IDLE_ENTRY_INSTRUCTIONS: u32 = 130 + 2 * DMA_CHUNK;

/// The F411's half/full-transfer interrupt's own work around `Stream::piece` (the DMA flags
/// read and cleared, NDTR, `RingWalker::walk`, the statistics, the `Tee` copy of 16 bytes):
/// ≈ 75, **estimated** from `crates/bsp/src/f411.rs`, not measured; with the measured piece it gives
/// the chunk cost of [`foreign_load_per_mille`].
pub const F411_CHUNK_ENTRY_INSTRUCTIONS: u32 = 75;

/// The worst finish the model charges at `rate`: [`LINE_BUDGET_INSTRUCTIONS`] when the F411
/// receives one character per interrupt, [`DMA_FINISH_INSTRUCTIONS`] in the DMA mode.
pub const fn budget_instructions(rate: Baudrate) -> u32 {
    if per_character(rate) {
        LINE_BUDGET_INSTRUCTIONS
    } else {
        DMA_FINISH_INSTRUCTIONS
    }
}

/// Core clock of the F411 build (HCLK = 96 MHz, `crates/bsp/src/f411.rs`), cycles per second.
pub const CPU_HZ: u32 = 96_000_000;
/// Cortex-M4F exception entry (ARM DDI 0439 §3.3: 12 cycles, lazy FPU stacking); the RTIC
/// dispatch and everything after it are in the measured instructions.
pub const INTERRUPT_ENTRY_CYCLES: u32 = 12;
/// Per-character receive (≤ [`PER_CHARACTER_MAX_BPS`]): RXNE is set at most one bit after
/// the middle of the last stop bit (RM0383 §19.3.3) — charged as one bit after its end.
pub const RXNE_BITS: u32 = 1;
/// DMA receive (above [`PER_CHARACTER_MAX_BPS`]): the end of a request is found by USART
/// IDLE (RM0383 §19.3.4: set after one idle character, 11 bit times after the last stop bit),
/// plus one bit of detection uncertainty: 12 bit times.
pub const IDLE_DETECT_BITS: u32 = 12;
/// The F411's receive DMA ring (bytes); its half- and full-transfer interrupts hand the
/// telegram's bytes to the fast path in chunks of half the ring as they arrive.
pub const DMA_RING: u32 = 32;
/// One chunk of the ring ([`DMA_RING`] / 2): at IDLE at most `DMA_CHUNK - 1` characters
/// wait for the sink.
pub const DMA_CHUNK: u32 = DMA_RING / 2;
/// The highest rate received with one interrupt per character (1.5 Mbit/s: 11 bits = 704
/// cycles per character); above it the DMA ring.
pub const PER_CHARACTER_MAX_BPS: u32 = 1_500_000;
/// Start of the transmit: the first character into DR, or the DMA stream NDTR/EN, DE and
/// USART CR3.DMAT writes, rounded up.
pub const DMA_START_CYCLES: u32 = 60;
/// CPI bound for the line code in SRAM (no flash wait states; fetches share the bus with data
/// and DMA): 3/2.
pub const CPI_NUM: u32 = 3;
/// Denominator of the CPI bound.
pub const CPI_DEN: u32 = 2;
/// Margin on the modelled time, percent.
pub const MARGIN_PERCENT: u32 = 20;
/// Lowest declared value: 15 bit times (≥ min_TSDR 11 + 4; IDLE detection + 3).
pub const MAX_TSDR_FLOOR: u32 = IDLE_DETECT_BITS + 3;

/// The customary standard maxima (reference §1.2), 1000 at 12 Mbit/s: the value declared before
/// the cycle model and its ceiling.
pub const fn customary_max_tsdr(rate: Baudrate) -> u16 {
    match rate {
        Baudrate::B9600 | Baudrate::B19200 | Baudrate::B93750 | Baudrate::B187500 => 60,
        Baudrate::B45450 => 250,
        Baudrate::B500k => 100,
        Baudrate::B1500k => 150,
        Baudrate::B3M => 250,
        Baudrate::B6M => 450,
        Baudrate::B12M => 1000,
    }
}

/// Whether the F411 receives at `rate` with one interrupt per character (else the DMA ring).
pub const fn per_character(rate: Baudrate) -> bool {
    rate.bits_per_second() <= PER_CHARACTER_MAX_BPS
}

/// The cycle model of the response time on the F411 with the streaming receive (issue 11), in
/// bit times after the request's last stop bit, for a worst finish of `instructions`:
///
/// * **≤ 1.5 Mbit/s, one interrupt per character, end by length**: [`RXNE_BITS`] + ⌈(interrupt
///   entry + `instructions` × CPI + transmit start) / cycles per bit⌉;
/// * **≥ 3 Mbit/s, DMA ring, end by IDLE**: [`IDLE_DETECT_BITS`] + ⌈(interrupt entry +
///   (`instructions` + [`F411_IDLE_ENTRY_INSTRUCTIONS`]) × CPI + DMA start) / cycles per bit⌉
///   — `instructions` measured with the DMA receive emulated ([`DMA_FINISH_INSTRUCTIONS`]:
///   the remainder the chunk interrupts left, the decision), the handler's register work
///   estimated;
///
/// plus the margin; never below [`MAX_TSDR_FLOOR`].
pub const fn modelled_tsdr(rate: Baudrate, instructions: u32) -> u32 {
    let (wait_bits, work) = if per_character(rate) {
        (RXNE_BITS, instructions)
    } else {
        (IDLE_DETECT_BITS, instructions + F411_IDLE_ENTRY_INSTRUCTIONS)
    };
    let cycles = INTERRUPT_ENTRY_CYCLES + work * CPI_NUM / CPI_DEN + DMA_START_CYCLES;
    let cycles_per_bit = CPU_HZ / rate.bits_per_second();
    let bits = wait_bits + cycles.div_ceil(cycles_per_bit);
    let with_margin = (bits * (100 + MARGIN_PERCENT)).div_ceil(100);
    if with_margin < MAX_TSDR_FLOOR {
        MAX_TSDR_FLOOR
    } else {
        with_margin
    }
}

/// The CPU share (per mille) of a saturated bus of other stations' telegrams of `len`
/// characters each at `rate` in the F411's DMA mode: per telegram (`len` × 11 bit times plus
/// the 33-bit idle T_SYN before it) `len` / [`DMA_CHUNK`] chunk interrupts of
/// `chunk_instructions` each and one IDLE interrupt of `idle_instructions`, each with the
/// interrupt entry, at the CPI bound.
pub const fn foreign_load_per_mille(rate: Baudrate, len: u32, chunk_instructions: u32, idle_instructions: u32) -> u32 {
    let bits = len * 11 + 33;
    let chunk = INTERRUPT_ENTRY_CYCLES + chunk_instructions * CPI_NUM / CPI_DEN;
    let idle = INTERRUPT_ENTRY_CYCLES + idle_instructions * CPI_NUM / CPI_DEN;
    // cycles per telegram × telegrams per second / CPU_HZ, per mille.
    let cycles = (len * chunk).div_ceil(DMA_CHUNK) + idle;
    let per_s = rate.bits_per_second() as u64 / bits as u64;
    ((cycles as u64 * per_s * 1000).div_ceil(CPU_HZ as u64)) as u32
}

/// The cycles one chunk interrupt of the F411's DMA mode may take at `rate` before the DMA laps
/// the reader (`phy::ring::RingWalker`: both HT and TC pending at the next event, an overrun
/// that drops the telegram): the time of [`DMA_RING`] characters of 11 bits, counted from the
/// handler's NDTR read. A handler slower than one chunk's time (a first chunk that prepares a
/// long answer) is caught up by the next ones, which are short; one slower than this is not.
pub const fn ring_lap_cycles(rate: Baudrate) -> u32 {
    DMA_RING * 11 * (CPU_HZ / rate.bits_per_second())
}

/// The cycles of a chunk interrupt that runs `instructions` in the fast path's sink on the
/// F411: the interrupt entry and, at the CPI bound, the measured piece with the handler's own
/// register work ([`F411_CHUNK_ENTRY_INSTRUCTIONS`], estimated).
pub const fn chunk_cycles(instructions: u32) -> u32 {
    INTERRUPT_ENTRY_CYCLES + (instructions + F411_CHUNK_ENTRY_INSTRUCTIONS) * CPI_NUM / CPI_DEN
}

/// Whether the GSD's MaxTsdr follow the cycle model ([`modelled_tsdr`]): **yes** (issue 11).
/// [`LINE_BUDGET_INSTRUCTIONS`] and [`DMA_FINISH_INSTRUCTIONS`] are measured on the QEMU
/// builds' fast path (`fast::FastPath` behind the `phy::stream::TelegramSink` seam, the worst
/// request the fast path answers); the F411 runs the same fast path from its receive
/// interrupts at the top priority, with no lock shared with a lower task on the answer's way
/// (README "The response path"), and the model adds what QEMU does not execute: the receive
/// latency (RXNE, or IDLE), the interrupt entry, the DMA mode's IDLE handler register work
/// ([`F411_IDLE_ENTRY_INSTRUCTIONS`], estimated) and the transmit start, at a CPI of 1.5,
/// plus 20 %. Never above [`customary_max_tsdr`]. Not yet
/// measured on the board itself (no timing test here can): a response the board makes later
/// than this is dropped by the line (`TxDrop::TooLate`, counted) and the master repeats the
/// request.
pub const GSD_FROM_MODEL: bool = true;

/// GSD `MaxTsdr_<rate>`: the latest a response starts after the request's last stop bit, in
/// bit times, per rate: with [`GSD_FROM_MODEL`], [`modelled_tsdr`] of
/// [`budget_instructions`], never above [`customary_max_tsdr`] (today); without it, the
/// customary value (README "Board budget"). The host simulator holds every response to them;
/// the line drops a response later than this (`TxDrop::TooLate`).
pub const fn max_tsdr(rate: Baudrate) -> u16 {
    // A table computed at compile time: the line reads it per response, with no division.
    MAX_TSDR[rate as usize]
}

/// [`max_tsdr`] per rate, indexed by the `Baudrate` discriminant (`Baudrate::ALL` order).
const MAX_TSDR: [u16; 10] = {
    let mut t = [0u16; 10];
    let mut i = 0;
    while i < 10 {
        let rate = Baudrate::ALL[i];
        t[rate as usize] = declared_max_tsdr(rate);
        i += 1;
    }
    t
};

/// The value [`max_tsdr`] declares (see there).
const fn declared_max_tsdr(rate: Baudrate) -> u16 {
    let ceiling = customary_max_tsdr(rate);
    let m = modelled_tsdr(rate, budget_instructions(rate));
    if !GSD_FROM_MODEL || m > ceiling as u32 {
        ceiling
    } else {
        m as u16
    }
}

/// GSD `Min_Slave_Intervall` in units of 100 µs.
pub const MIN_SLAVE_INTERVAL_100US: u16 = 1;

/// GSD `Freeze_Mode_supp`.
pub const FREEZE_MODE_SUPP: bool = true;
/// GSD `Sync_Mode_supp`.
pub const SYNC_MODE_SUPP: bool = true;
/// GSD `Fail_Safe`: zero-length Data_Exchange outputs are accepted as "clear" (reference §3.7).
pub const FAIL_SAFE: bool = true;
/// GSD `Set_Slave_Add_supp`.
pub const SET_SLAVE_ADD_SUPP: bool = true;
/// GSD `Auto_Baud_supp`.
pub const AUTO_BAUD_SUPP: bool = true;
/// GSD `DPV1_Slave`: Set_Prm may set DPV1_Enable; MSAC_C1 then opens in data exchange.
pub const DPV1_SLAVE: bool = true;
/// GSD `C1_Read_Write_supp`: MSAC_C1 DS_Read / DS_Write.
pub const C1_READ_WRITE_SUPP: bool = true;
/// GSD `C1_Max_Data_Len`: data bytes per MSAC_C1 PDU after the 4-byte header.
pub const C1_MAX_DATA_LEN: usize = 240;
/// GSD `C1_Response_Timeout` in 10 ms units: how long a class-1 master polls for a response.
/// The card answers record requests at its next processing turn (≤ a few ms); 1 s leaves room
/// for drive parameters fetched through the DPM mailbox.
pub const C1_RESPONSE_TIMEOUT_10MS: u16 = 100;
/// The application profile the card implements, as the GSD states it (comment line
/// `Profile: PROFIdrive …, Profile_Ident_Number 0x3A00`, next to `Slave_Family = 1@Drives`):
/// PROFIdrive, profile ident number 0x3A00 (reference §4.7: I&M0 PROFILE_ID 0x3A00 =
/// PROFIdrive; PNU 965 carries its version, 4.1). Sent as Profile_Ident_Number in the
/// MSAC_C2 Initiate.res (reference §4.5).
pub const PROFILE_IDENT_NUMBER: u16 = 0x3A00;
/// The slot of the drive module (GSD `SlotDefinition`: `Slot(1) = "Drive telegram" 1 1-4001`,
/// every module allowed): the configuration's one module is slot 1, the device itself slot 0.
pub const DRIVE_MODULE_SLOT: u8 = 1;
/// The DP-V1 slots at which the drive's data records (PROFIdrive record 47, WEG record 48)
/// answer: the device (slot 0, as Balluff, VACON and WEG address it) and the drive module's
/// slot (as ABB adapters and SINAMICS address the drive object; reference §5.1).
pub const RECORD_SLOTS: [u8; 2] = [0, DRIVE_MODULE_SLOT];
/// The DPM IDENT block of this card (`dpm::Identity`: card type, firmware version, the GSD
/// [`IDENT_NUMBER`]; the serial number from the platform).
pub const IDENTITY: crate::dpm::Identity = crate::dpm::Identity::of_product(IDENT_NUMBER).with_firmware(
    env!("CARGO_PKG_VERSION_MAJOR"),
    env!("CARGO_PKG_VERSION_MINOR"),
    env!("CARGO_PKG_VERSION_PATCH"),
);
// The DPM carries every module's cyclic images whole (the benchmark build's 244-byte module does
// not: its data is cut to `dpm::layout::PD_CAPACITY`, `ProcessData::new`, see `BENCH_244`), and
// the drive's extended diagnosis fits the slave's.
#[cfg(not(feature = "bench"))]
const _: () =
    assert!(crate::dpm::layout::PD_CAPACITY >= MAX_INPUT_LEN && crate::dpm::layout::PD_CAPACITY >= MAX_OUTPUT_LEN);
const _: () = assert!(crate::dpm::layout::EXT_DIAG_CAPACITY <= MAX_EXT_DIAG_LEN);
const _: () = assert!(USER_PRM_LEN <= crate::dpm::USER_PRM_CAPACITY);
/// This card's PROFIdrive data records: at [`RECORD_SLOTS`], and PNU 964 (drive unit
/// identification, OPTE3/E5 Table 110 structure) with manufacturer 0 (the PI vendor ID, a
/// placeholder until registered), drive unit type = [`IDENT_NUMBER`], software version 1,
/// firmware year 2026, day/month 2211, one drive object.
pub const RECORDS: crate::profile::records::RecordConfig =
    crate::profile::records::RecordConfig { slots: &RECORD_SLOTS, device_id: [0, IDENT_NUMBER, 1, 2026, 2211, 1] };
/// GSD `C2_Read_Write_supp`: MSAC_C2 connections (commissioning tools).
pub const C2_READ_WRITE_SUPP: bool = true;
/// GSD `C2_Max_Data_Len`.
pub const C2_MAX_DATA_LEN: usize = 240;
/// GSD `C2_Response_Timeout` in 10 ms units.
pub const C2_RESPONSE_TIMEOUT_10MS: u16 = 100;
/// GSD `C2_Max_Count_Channels`: simultaneous MSAC_C2 connections.
pub const C2_MAX_COUNT_CHANNELS: usize = 2;
/// GSD `Max_Initiate_PDU_Length`: the longest Initiate request accepted — any that fits the
/// 244-byte MSAC_C2 PDU.
pub const MAX_INITIATE_PDU_LENGTH: usize = 244;
/// GSD `WD_Base_1ms_supp`: the 1 ms watchdog base of DPV1_Status_1 bit 2 is supported.
pub const WD_BASE_1MS_SUPP: bool = true;

/// GSD `Max_Diag_Data_Len`: the whole Slave_Diag response DU (6 standard octets + extended).
pub const MAX_DIAG_DATA_LEN: usize = 64;
/// Room for extended diagnosis after the 6 standard octets.
pub const MAX_EXT_DIAG_LEN: usize = MAX_DIAG_DATA_LEN - 6;

/// GSD `Max_Input_Len` / `Max_Output_Len`: the largest cyclic images of any module (VACON
/// telegram 139, 18 words each way). The DPM carries them whole:
/// `dpm::layout::PD_CAPACITY` (64 bytes) ≥ 36 (asserted below).
#[cfg(not(feature = "bench"))]
pub const MAX_INPUT_LEN: usize = 36;
/// See [`MAX_INPUT_LEN`].
#[cfg(not(feature = "bench"))]
pub const MAX_OUTPUT_LEN: usize = 36;
/// The benchmark build (feature `bench`, not in the GSD): room for [`BENCH_244`].
#[cfg(feature = "bench")]
pub const MAX_INPUT_LEN: usize = 244;
/// See [`MAX_INPUT_LEN`].
#[cfg(feature = "bench")]
pub const MAX_OUTPUT_LEN: usize = 244;
/// GSD `Max_Module`: one drive module per configuration (OPTE3/E5 §5.3 drive module rules:
/// only one drive module is allowed, one must always be configured). The card has no safety
/// slot, so OPTE3/E5 Table 12's "Empty" placeholder for slot 1 has no use here.
pub const MAX_MODULE: u8 = 1;

/// The largest GSD module fits the DPM's process-data blocks.
#[cfg(not(feature = "bench"))]
const _: () =
    assert!(MAX_INPUT_LEN <= crate::dpm::layout::PD_CAPACITY && MAX_OUTPUT_LEN <= crate::dpm::layout::PD_CAPACITY);

/// One cyclic-data module the card offers (a GSD `Module`, [`dp::cfg::Module`]). The
/// reference numbers: 1 / 20 for Standard Telegram 1 / 20, 101..=106 for PPO 1..6, family
/// tag × 1000 + telegram number for a manufacturer's telegram (`dpm::Family`: 1 VACON, 2 WEG
/// CFW500, 3 WEG CFW-11, 4 INVT).
pub use crate::dp::cfg::Module;

/// A manufacturer telegram of `words` consistent words each way in the special identifier
/// format: `C4` (output and input length bytes, 4 manufacturer bytes), the length bytes,
/// then `FE <family tag> <telegram number, 2 bytes>`.
macro_rules! vendor_module {
    ($name:literal, $family:literal, $number:literal, $words:literal) => {
        Module {
            name: $name,
            reference: $family * 1000 + $number,
            cfg: &[0xC4, 0xC0 | ($words - 1), 0xC0 | ($words - 1), 0xFE, $family, 0x00, $number],
            inputs: 2 * $words,
            outputs: 2 * $words,
        }
    };
}

/// Every module of the GSD, in GSD order.
///
/// **Identifier choice** (reference §3.4). A module is recognised by its bytes alone, so no
/// two modules may share them, and the general format says only "n words": VACON telegram
/// 100, CFW500 telegram 106 and CFW-11 telegram 103 are all 6 words each way, which is also
/// PPO 4's `F5`. Hence:
/// * PROFIdrive standard telegrams use the special identifier format with three
///   manufacturer bytes `FD <telegram number, 2 bytes>` naming the telegram, as SINAMICS
///   GSDs do: ST1 = `C3 C1 C1 FD 00 01` (out 2 words, in 2 words, consistent), ST20 =
///   `C3 C1 C5 FD 00 14` (out 2 words, in 6 words).
/// * Manufacturer telegrams use four manufacturer bytes `FE <family tag> <number>`, because
///   telegram numbers collide across families (VACON 100 ≠ CFW-11 100, CFW500 103 ≠
///   CFW-11 103): VACON 100 = `C4 C5 C5 FE 01 00 64`.
/// * The PPO types keep the classic general identifiers of PROFIdrive 2.0 drives: PKW = `F3`
///   (4 words in/out, consistent), PZD 2/6/10 words = `F1`/`F5`/`F9` (OPTE3/E5 §6.5.4,
///   reference §5.5), so existing PLC projects keep working.
/// * The INVT frame (PKW + CW/SW + PZD2..PZD12, INVT manual §2.6) is PPO-like and uses the
///   general format too: `F3 FB` (PKW, then 12 words consistent), which no other module has.
///   The INVT manual shows one frame layout only (every example carries PZD2..PZD12; an unused
///   word is switched off by mapping it to "0: invalid" in P15.02–P15.23, not by a shorter
///   telegram), so there is one INVT module.
///
/// `host-tests/tests/gsd.rs` checks this list against the GSD and that no two modules share
/// their bytes; `dp::cfg` refuses a concatenation of two modules (one drive module only).
pub const MODULES: &[Module] = &[
    Module {
        name: "Standard telegram 1, PZD-2/2",
        reference: 1,
        cfg: &[0xC3, 0xC1, 0xC1, 0xFD, 0x00, 0x01],
        inputs: 4,
        outputs: 4,
    },
    Module {
        name: "Standard telegram 20, PZD-2/6",
        reference: 20,
        cfg: &[0xC3, 0xC1, 0xC5, 0xFD, 0x00, 0x14],
        inputs: 12,
        outputs: 4,
    },
    vendor_module!("VACON telegram 100, PZD-6/6", 1, 100, 6),
    vendor_module!("VACON telegram 101, PZD-10/10", 1, 101, 10),
    vendor_module!("VACON telegram 138, PZD-14/14", 1, 138, 14),
    vendor_module!("VACON telegram 139, PZD-18/18", 1, 139, 18),
    Module { name: "PPO 1, PKW + PZD-2/2", reference: 101, cfg: &[0xF3, 0xF1], inputs: 12, outputs: 12 },
    Module { name: "PPO 2, PKW + PZD-6/6", reference: 102, cfg: &[0xF3, 0xF5], inputs: 20, outputs: 20 },
    Module { name: "PPO 3, PZD-2/2", reference: 103, cfg: &[0xF1], inputs: 4, outputs: 4 },
    Module { name: "PPO 4, PZD-6/6", reference: 104, cfg: &[0xF5], inputs: 12, outputs: 12 },
    Module { name: "PPO 5, PKW + PZD-10/10", reference: 105, cfg: &[0xF3, 0xF9], inputs: 28, outputs: 28 },
    Module { name: "PPO 6, PZD-10/10", reference: 106, cfg: &[0xF9], inputs: 20, outputs: 20 },
    vendor_module!("CFW500 telegram 103, PZD-3/3", 2, 103, 3),
    vendor_module!("CFW500 telegram 104, PZD-4/4", 2, 104, 4),
    vendor_module!("CFW500 telegram 105, PZD-5/5", 2, 105, 5),
    vendor_module!("CFW500 telegram 106, PZD-6/6", 2, 106, 6),
    vendor_module!("CFW500 telegram 107, PZD-7/7", 2, 107, 7),
    vendor_module!("CFW500 telegram 108, PZD-8/8", 2, 108, 8),
    vendor_module!("CFW-11 telegram 100, PZD-3/3", 3, 100, 3),
    vendor_module!("CFW-11 telegram 101, PZD-4/4", 3, 101, 4),
    vendor_module!("CFW-11 telegram 102, PZD-5/5", 3, 102, 5),
    vendor_module!("CFW-11 telegram 103, PZD-6/6", 3, 103, 6),
    vendor_module!("CFW-11 telegram 104, PZD-7/7", 3, 104, 7),
    vendor_module!("CFW-11 telegram 105, PZD-8/8", 3, 105, 8),
    vendor_module!("CFW-11 telegram 106, PZD-9/9", 3, 106, 9),
    vendor_module!("CFW-11 telegram 107, PZD-10/10", 3, 107, 10),
    Module { name: "INVT PKW + PZD-12/12", reference: 4001, cfg: &[0xF3, 0xFB], inputs: 32, outputs: 32 },
    #[cfg(feature = "bench")]
    BENCH_32,
    #[cfg(feature = "bench")]
    BENCH_244,
];

/// Benchmark build only (feature `bench`; not in the GSD, no DPM telegram): 16 words in and
/// out, consistent (`FF`) — Data_Exchange with 32 bytes each way (README "Benchmark").
#[cfg(feature = "bench")]
pub const BENCH_32: Module = Module { name: "Bench 32/32", reference: 9032, cfg: &[0xFF], inputs: 32, outputs: 32 };

/// Benchmark build only (feature `bench`; not in the GSD, no DPM telegram): the longest
/// cyclic images, 244 bytes each way — special format `C0 FF FF` (out 64 words, in 64 words,
/// consistent) then `C0 F9 F9` (out 58 words, in 58 words).
///
/// The DPM's process-data blocks hold [`crate::dpm::layout::PD_CAPACITY`] bytes, and the DPM
/// has no telegram code for these modules: OUTPUTS carries the first 64 output bytes with
/// telegram 0, the simulated drive does not answer a layout it does not know, and the master
/// reads zeros as inputs. The protocol path (framer, DP slave, staged 244-byte response) is
/// the full length.
#[cfg(feature = "bench")]
pub const BENCH_244: Module = Module {
    name: "Bench 244/244",
    reference: 9244,
    cfg: &[0xC0, 0xFF, 0xFF, 0xC0, 0xF9, 0xF9],
    inputs: 244,
    outputs: 244,
};

/// Find the module whose configuration bytes are exactly `cfg`.
pub fn module_for_cfg(cfg: &[u8]) -> Option<&'static Module> {
    dp::cfg::module_for_cfg(cfg, MODULES)
}

/// One user parameter byte of Set_Prm (a GSD `ExtUserPrmData`, [`dp::prm::UserPrm`]).
pub use crate::dp::prm::UserPrm;

/// Operate mode (OPTE3/E5 §5.3 Table 13): 0 = Local (drive decides), 1 = Remote PROFIdrive,
/// 2 = Remote Bypass, 3 = Remote Echo.
pub const PRM_OPERATE_MODE: UserPrm =
    UserPrm { reference: 1, offset: 3, name: "Operate mode", default: 0, min: 0, max: 3 };
/// Reaction to communication loss (watchdog, Clear, master loss) requested from the drive:
/// 0 = as configured in the drive (P0313-style), 1 = ramp stop (OFF1), 2 = coast (OFF2),
/// 3 = quick stop (OFF3), 4 = hold last setpoint, and WEG P0313's options 3 / 4 / 5 (CFW500
/// Table 4.1): 5 = change to local, 6 = change to local keeping commands and reference,
/// 7 = fault (also when the drive is not controlled via the network). The drive's
/// `DriveCommand::comm_loss_reaction` carries the same codes.
pub const PRM_COMM_LOSS_REACTION: UserPrm =
    UserPrm { reference: 2, offset: 4, name: "Communication loss reaction", default: 0, min: 0, max: 7 };

/// All user parameters after the three DPV1 status bytes, in offset order.
pub const USER_PRMS: &[UserPrm] = &[PRM_OPERATE_MODE, PRM_COMM_LOSS_REACTION];

/// GSD `Max_User_Prm_Data_Len`: 3 DPV1 status bytes + the user parameters.
pub const USER_PRM_LEN: usize = 5;

/// The default User_Prm_Data (GSD `Ext_User_Prm_Data_Const(0)` with every default applied).
pub const USER_PRM_DEFAULTS: [u8; USER_PRM_LEN] =
    [0x00, 0x00, 0x00, PRM_OPERATE_MODE.default, PRM_COMM_LOSS_REACTION.default];

/// This card as the DP slave checks it (Set_Prm ident check, User_Prm_Data length and
/// ranges, Sync / Freeze / DP-V1 / alarm support, Chk_Cfg against [`MODULES`], Real_Cfg,
/// `Max_Diag_Data_Len`): the constants above, with [`OperateModePolicy`].
pub const SLAVE: dp::SlaveConfig = dp::SlaveConfig {
    ident_number: IDENT_NUMBER,
    default_address: DEFAULT_ADDRESS,
    modules: MODULES,
    user_prm_len: USER_PRM_LEN,
    user_prm_defaults: &USER_PRM_DEFAULTS,
    user_prms: USER_PRMS,
    freeze_mode_supp: FREEZE_MODE_SUPP,
    sync_mode_supp: SYNC_MODE_SUPP,
    fail_safe: FAIL_SAFE,
    dpv1_slave: DPV1_SLAVE,
    wd_base_1ms_supp: WD_BASE_1MS_SUPP,
    diagnostic_alarm_supp: DIAGNOSTIC_ALARM_SUPP,
    max_diag_data_len: MAX_DIAG_DATA_LEN,
    cfg_policy: &OperateModePolicy,
};

// The card fits the DP slave's compile-time buffers (dp::MAX_INPUT_LEN / MAX_OUTPUT_LEN,
// dp::diag::MAX_DIAG_DATA_LEN, dp::prm::MAX_USER_PRM_LEN) and its tables are well formed.
const _: () = assert!(SLAVE.fits());
const _: () = assert!(MAX_INPUT_LEN <= dp::MAX_INPUT_LEN && MAX_OUTPUT_LEN <= dp::MAX_OUTPUT_LEN);
const _: () = assert!(MAX_DIAG_DATA_LEN <= dp::diag::MAX_DIAG_DATA_LEN);
const _: () = assert!(MAX_EXT_DIAG_LEN <= dp::diag::MAX_EXT_DIAG_LEN);
const _: () = assert!(USER_PRM_LEN <= dp::prm::MAX_USER_PRM_LEN);
const _: () = assert!(PRM_OPERATE_MODE.offset < USER_PRM_LEN && PRM_COMM_LOSS_REACTION.offset < USER_PRM_LEN);

/// The module reference of Standard Telegram 20 (PZD-2/6), which [`OperateModePolicy`] limits.
const ST20_REFERENCE: u16 = 20;

/// This card's Chk_Cfg rule ([`dp::CfgPolicy`]), the operate mode rule of the profile: with
/// the Set_Prm user parameter [`PRM_OPERATE_MODE`] = 2 Remote Bypass or 3 Remote Echo,
/// Standard Telegram 20 is refused (OPTE3/E5 §5.1.5: "only PROFIdrive mode is allowed" with
/// ST20) → [`dp::cfg::CfgError::NotAllowedInOperateMode`], Cfg_Fault.
///
/// Why at Chk_Cfg and not in Set_Prm: the master sends Set_Prm *before* Chk_Cfg, so when the
/// mode arrives the module is not known yet; the forbidden pair is a configuration error,
/// which OPTE3/E5 §5.3 answers with the configuration fault ("an invalid module
/// configuration causes a diagnostic configuration fault"). A mode chosen locally in the
/// drive (operate mode 0) is checked by `profile::cyclic::Cyclic::new` instead.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OperateModePolicy;

impl dp::CfgPolicy for OperateModePolicy {
    fn check_cfg(&self, module: &Module, user_prm: &[u8]) -> Result<(), dp::cfg::CfgError> {
        let operate_mode = user_prm.get(PRM_OPERATE_MODE.offset).copied().unwrap_or(0);
        if module.reference == ST20_REFERENCE && matches!(operate_mode, 2 | 3) {
            return Err(dp::cfg::CfgError::NotAllowedInOperateMode);
        }
        Ok(())
    }
}

// ---- Identification & Maintenance (I&M0, reference §4.7; `dpv1::im`) ----

/// I&M0 MANUFACTURER_ID: the PI vendor ID. **Placeholder** 0 until registered (as PNU 964).
pub const IM_MANUFACTURER_ID: u16 = 0;
/// I&M0 ORDER_ID (≤ 20 characters, blank-padded): the GSD's `OrderNumber`.
pub const IM_ORDER_ID: &str = "ODC-PB1";
/// I&M0 HARDWARE_REVISION when the drive reports none (DPM `IDENT`): the GSD's
/// `Hardware_Release` "V0.1" as 1.
pub const IM_HARDWARE_REVISION: u16 = 1;
/// I&M0 SOFTWARE_REVISION: `V` + major, minor, patch — the GSD's `Software_Release` "V0.1.0".
pub const IM_SOFTWARE_REVISION: [u8; 4] = [b'V', 0, 1, 0];
/// This card's I&M0 values for `dpv1::im` (the constants above).
pub const IM: crate::dpv1::im::ImDevice = crate::dpv1::im::ImDevice {
    manufacturer_id: IM_MANUFACTURER_ID,
    order_id: IM_ORDER_ID,
    hardware_revision: IM_HARDWARE_REVISION,
    software_revision: IM_SOFTWARE_REVISION,
    profile_id: crate::dpv1::im::PROFILE_ID_PROFIDRIVE,
};
// The MSAC_C2 connections fit the I&M relations (1 + C2_Max_Count_Channels).
const _: () = assert!(C2_MAX_COUNT_CHANNELS < crate::dpv1::im::RELATIONS);
// The node keeps exactly the connections the GSD states.
const _: () = assert!(C2_MAX_COUNT_CHANNELS == crate::node::C2_CHANNELS);

/// This card's node over `slave` (see [`dp::DpSlave::with_address_lock`] for a stored
/// address): its I&M0 values ([`IM`]) and PROFIdrive as the MSAC_C2 Profile_Ident_Number
/// ([`PROFILE_IDENT_NUMBER`]), [`Node::with_device`](crate::node::Node::with_device). A free
/// function, not `Node::new`: the node is the crate `pbcard-link`'s, below the product.
pub const fn node(slave: dp::DpSlave) -> crate::node::Node {
    crate::node::Node::with_device(slave, &IM, PROFILE_IDENT_NUMBER)
}
/// GSD `Ident_Maintenance_supp`: I&M0–I&M4 at slot 0 / index 255 over MSAC_C1 and MSAC_C2.
pub const IDENT_MAINTENANCE_SUPP: bool = true;

// ---- DP-V1 alarms (reference §4.4; `dp::alarm`) ----

/// GSD `Diagnostic_Alarm_supp`: diagnostic alarms when the drive faults and when the fault
/// clears, enabled by DPV1_Status_2 b5.
pub const DIAGNOSTIC_ALARM_SUPP: bool = true;
/// GSD `Process_Alarm_supp`, `Pull_Plug_Alarm_supp`, `Status_Alarm_supp`, `Update_Alarm_supp`,
/// `Manufacturer_Specific_Alarm_supp`: not offered (status travels in the Status_Message
/// block of the diagnosis, which needs no acknowledgement).
pub const OTHER_ALARMS_SUPP: bool = false;
/// GSD `Extra_Alarm_SAP_supp`: Alarm_Ack on SAP 51 only (not SAP 50).
pub const EXTRA_ALARM_SAP_SUPP: bool = false;
/// GSD `Alarm_Sequence_Mode_Count`: outstanding alarms at most in sequence mode.
pub const ALARM_SEQUENCE_MODE_COUNT: usize = crate::dp::alarm::MAX_OUTSTANDING;
/// GSD `Alarm_Type_Mode_supp`: type mode (Alarm_Mode 0, one alarm per type) supported.
pub const ALARM_TYPE_MODE_SUPP: bool = true;

#[cfg(test)]
mod max_tsdr_model {
    use super::*;

    const RATES: [Baudrate; 10] = [
        Baudrate::B9600,
        Baudrate::B19200,
        Baudrate::B45450,
        Baudrate::B93750,
        Baudrate::B187500,
        Baudrate::B500k,
        Baudrate::B1500k,
        Baudrate::B3M,
        Baudrate::B6M,
        Baudrate::B12M,
    ];

    #[test]
    fn max_tsdr_is_the_model_capped_by_the_customary_value() {
        for rate in RATES {
            let v = u32::from(max_tsdr(rate));
            let model = modelled_tsdr(rate, budget_instructions(rate));
            println!("{rate:?}: model {model} → MaxTsdr {v}");
            assert!(v >= MAX_TSDR_FLOOR, "{rate:?}: {v} below the floor");
            assert!(v <= u32::from(customary_max_tsdr(rate)), "{rate:?}: {v} above the customary value");
            // Independently: the model's time in seconds with the margin, rounded up — per
            // character up to 1.5 Mbit/s (RXNE), the DMA ring above (IDLE) with its own
            // measured finish and the IDLE handler's estimated register work.
            let dma = rate.bits_per_second() > 1_500_000;
            let work = if dma {
                f64::from(DMA_FINISH_INSTRUCTIONS + F411_IDLE_ENTRY_INSTRUCTIONS)
            } else {
                f64::from(LINE_BUDGET_INSTRUCTIONS)
            };
            let cycles = f64::from(INTERRUPT_ENTRY_CYCLES) + work * 1.5 + f64::from(DMA_START_CYCLES);
            let wait = if dma { IDLE_DETECT_BITS } else { RXNE_BITS };
            let bits = f64::from(wait) + (cycles * f64::from(rate.bits_per_second()) / 96e6).ceil();
            let expect = ((bits * 1.2).ceil() as u32).max(MAX_TSDR_FLOOR);
            assert_eq!(model, expect, "{rate:?}: the model");
            let declared = if GSD_FROM_MODEL {
                expect.min(u32::from(customary_max_tsdr(rate)))
            } else {
                u32::from(customary_max_tsdr(rate))
            };
            assert_eq!(v, declared, "{rate:?}");
        }
    }

    /// The floor leaves room after the default min_TSDR (a response never due before it may start).
    const _: () = assert!(MAX_TSDR_FLOOR > crate::time::BitTimes::MIN_TSDR_DEFAULT.0);

    /// The ring's lap: 32 characters of 11 bits at 8 cycles a bit (12 Mbit/s at 96 MHz), at 32
    /// cycles a bit at 3 Mbit/s; a chunk interrupt's cycles at the CPI bound.
    #[test]
    fn ring_lap_and_chunk_cycles() {
        assert_eq!(ring_lap_cycles(Baudrate::B12M), 32 * 11 * 8);
        assert_eq!(ring_lap_cycles(Baudrate::B3M), 32 * 11 * 32);
        assert_eq!(chunk_cycles(0), 12 + 75 * 3 / 2);
        assert_eq!(chunk_cycles(1339), 12 + (1339 + 75) * 3 / 2);
        assert!(chunk_cycles(1339) < ring_lap_cycles(Baudrate::B12M));
    }

    /// The foreign-traffic model: a saturated 12 Mbit/s bus of 253-byte telegrams with
    /// 100-instruction chunks and 200-instruction IDLE ends: 12e6 / (253 × 11 + 33) telegrams
    /// per second × (253 / 16 × 162 + 312) cycles / 96e6.
    #[test]
    fn foreign_load_model() {
        let pm = foreign_load_per_mille(Baudrate::B12M, 253, 100, 200);
        let per_s = 12e6_f64 / (253.0 * 11.0 + 33.0);
        let cycles = (253.0 * 162.0 / 16.0_f64).ceil() + 312.0;
        let want = (cycles * per_s.floor() * 1000.0 / 96e6).ceil() as u32;
        assert_eq!(pm, want);
    }

    #[test]
    fn a_smaller_budget_never_raises_max_tsdr() {
        for rate in RATES {
            for smaller in [0, 100, LINE_BUDGET_INSTRUCTIONS / 2, LINE_BUDGET_INSTRUCTIONS - 1] {
                assert!(modelled_tsdr(rate, smaller) <= modelled_tsdr(rate, LINE_BUDGET_INSTRUCTIONS));
                assert!(modelled_tsdr(rate, smaller) <= modelled_tsdr(rate, DMA_FINISH_INSTRUCTIONS));
            }
        }
    }
}
