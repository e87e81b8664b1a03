//! The DPM transport on the board: a framed protocol over SPI between the drive's control
//! board (SPI **master**, "host") and the card (SPI **slave**), sans-IO (issue 7 item 4,
//! ARCHITECTURE §5). The card side is [`SpiSlave`]; the host side is [`SpiHostCodec`] (frame
//! encoder / reply decoder) and [`SpiHost`] (read / write over any full-duplex [`SpiBus`]);
//! [`Loopback`] is an in-process card that the QEMU build, the soft slave and the tests can
//! put behind [`SpiHost`]. The board driver (`crates/bsp/src/spi.rs`, STM32F411 SPI2 + DMA1) only
//! moves bytes; every decision is made here.
//!
//! # Byte-level specification (protocol version 2)
//!
//! **Electrical.** SPI mode 0 (CPOL = 0, CPHA = 0), 8-bit words, most significant bit first,
//! SCK up to 12 MHz. NSS (active low) frames a **transaction**: NSS falls, the master clocks
//! any number of bytes (at most [`MAX_TRANSACTION`]), NSS rises. The card's IRQ output
//! (active low) is described under "Events" below.
//!
//! **Timing, pins, timeouts** (design values for the F411 board, not measured on hardware):
//! NSS low at least 1 µs before the first SCK edge and high at least 1 µs after the last;
//! every NSS low phase is a transaction, one without clocks too (it is counted and ignored,
//! but the reply armed for it is gone): the master sends no NSS pulse without clocks. The
//! card drives MISO and IRQ push-pull once started; during its reset and start-up (a few ms)
//! both float: the host fits pull-ups on MISO (an absent card then reads `0xFF`, an invalid
//! RESULT), on IRQ (released = no events) and on NSS (a host in reset selects nothing).
//! Timeouts: the card counts the drive lost after 200 ms without a new `DRIVE.HEARTBEAT`
//! (A140 on the drive side is the host's own 200 ms default for `CARD.HEARTBEAT`), and
//! answers a parameter request the drive leaves unanswered for 500 ms itself (0x11 / 0xDD01).
//!
//! **Pipelining (depth 1).** SPI is full duplex, and a slave fed by DMA cannot compute an
//! answer within a byte time. Therefore the reply to the request sent in transaction *k* is
//! clocked out on MISO during transaction *k + 1* — in *k + 1* or never: the card arms it
//! the moment it is built, if *k + 1* has not begun; a reply built later is discarded, and
//! *k + 1* then carries `0x00` bytes only (first byte `0x00` = "no reply in this
//! transaction"). The master clocks at least as many bytes as the longer of (its request
//! frame, the reply it expects); the master pads its request with `0x00`, the card pads its
//! reply with `0x00`. Between NSS rising and the next NSS falling the master leaves the card
//! [`T_READY_US`] µs (a design target, not measured on hardware: the board's frame task
//! runs above the application step; see `crates/bsp/src/spi.rs`). Each reply echoes the request's
//! TAG, CMD and ADDR, and its DATA length is the one asked (a WRITE's reply carries the
//! request's CRC), so a reply is never taken for another request, a stale one of a
//! restarted host included. READ and WRITE are idempotent: a master that got no reply
//! (`0x00`, a damaged or a foreign one) repeats the request; it also repeats a request
//! refused with CRC_ERROR, BAD_LENGTH or BAD_COMMAND (a flipped bit in CMD or LEN moves the
//! CRC, so line errors show as these too), while BAD_ADDRESS and FORBIDDEN_WRITE are decided
//! on CRC-checked content and are final.
//!
//! **Request frame** (MOSI; big-endian):
//!
//! | byte | field | meaning |
//! |---|---|---|
//! | 0 | CMD | [`Command`]: `0xA1` READ, `0xB2` WRITE, `0xC4` STATUS, `0xD8` CYCLIC (version 2, below) |
//! | 1 | TAG | chosen by the master, echoed in the reply |
//! | 2..4 | ADDR | u16 offset in the DPM image (`docs/DPM.md`); STATUS: 0 |
//! | 4..6 | LEN | u16 data length: READ bytes wanted, WRITE bytes of DATA (1..=[`MAX_DATA`]); STATUS: 0; CYCLIC: bytes of DATA |
//! | 6..6+n | DATA | WRITE: n = LEN bytes for ADDR..; CYCLIC: the cycle's DATA (below) |
//! | 6+n..8+n | CRC | u16 [`crc16`] of bytes 0..6+n |
//! | 8+n.. | padding | `0x00` up to the end of the transaction |
//!
//! **Reply frame** (MISO, in the next transaction; big-endian):
//!
//! | byte | field | meaning |
//! |---|---|---|
//! | 0 | RESULT | [`ResultCode`]: `0x80` OK, `0x81` CRC error, `0x82` bad command, `0x83` bad length, `0x84` bad address, `0x85` forbidden write; `0x00` = no reply |
//! | 1 | TAG | the request's TAG (as received) |
//! | 2 | CMD | the request's CMD (as received) |
//! | 3 | FLAGS | bit 0: events pending (the IRQ line is asserted); other bits 0 |
//! | 4..6 | ADDR | the request's ADDR (as received) |
//! | 6..8 | LEN | u16 n = bytes of DATA that follow (READ OK: the LEN asked; WRITE OK: 2; STATUS OK: [`STATUS_LEN`]; else 0) |
//! | 8..8+n | DATA | READ: image bytes ADDR..ADDR+n; WRITE: the request's CRC (u16); STATUS: see below |
//! | 8+n..10+n | CRC | u16 [`crc16`] of bytes 0..8+n |
//! | 10+n.. | padding | `0x00` |
//!
//! **Checks, in this order** (the first that fails decides RESULT; each has a counter in
//! [`SpiStats`], shown in the STATUS data): transaction shorter than the frame its CMD and
//! LEN announce, or longer than [`MAX_TRANSACTION`] → BAD_LENGTH; CRC → CRC_ERROR; padding
//! not all `0x00` → BAD_LENGTH; CMD unknown (framed as header + CRC, no data) → BAD_COMMAND; LEN 0 or above [`MAX_DATA`]
//! (READ/WRITE), or ADDR/LEN not 0 (STATUS) → BAD_LENGTH; ADDR + LEN beyond the image →
//! BAD_ADDRESS; a WRITE touching a byte of a block the card writes (`layout::BLOCKS`, writer
//! "card") → FORBIDDEN_WRITE. A WRITE is applied to the image only after the whole frame has
//! passed every check, in one copy that the card's own accesses cannot interleave: a refused
//! or cut frame never changes a byte.
//!
//! **CRC**: CRC-16/CCITT-FALSE — polynomial `0x1021`, initial value `0xFFFF`, no reflection,
//! no final XOR; check value `crc16(b"123456789") = 0x29B1`. Sent high byte first.
//! Examples (CRCs cross-checked with Python's `binascii.crc_hqx(frame, 0xFFFF)`):
//! READ, TAG 1, ADDR 0x0010 (STATUS block), LEN 32 = `A1 01 00 10 00 20 67 C8`;
//! WRITE, TAG 2, ADDR 0x0078 (INPUTS), DATA `12 34` = `B2 02 00 78 00 02 12 34 07 2B`;
//! STATUS, TAG 3 = `C4 03 00 00 00 00 58 53`.
//!
//! **STATUS data** ([`STATUS_LEN`] = 20 bytes, big-endian): 0 protocol version (2), 1
//! reserved, 2..4 [`MAX_DATA`], 4..6 image size, 6..8 pending events (bitmap below), then
//! u16 counters (wrapping): 8 frames accepted, 10 CRC errors, 12 bad command, 14 bad length,
//! 16 bad address, 18 forbidden writes.
//!
//! **Events and the IRQ line.** Bit *i* of the pending-events bitmap stands for
//! `layout::BLOCKS[i]` (bit 1 STATUS, 2 OUTPUTS, 5 CARD, 8 MBX_REQ, 10 DRIVE_CMD — the
//! sequenced blocks the card writes). It is set while the block's `SEQ_HEAD` differs from the
//! value the host last read, and cleared by reading: an accepted READ whose range covers both
//! bytes of a block's `SEQ_HEAD` records the value sent; a CYCLIC reply counts as a read of
//! CARD, OUTPUTS and DRIVE_CMD (it carries their news), and of MBX_REQ when its MBX_REQ
//! fragment starts at offset 0 (at least 2 bytes, sent only while the block is consistent).
//! No separate acknowledge exists, so an update that comes after the host's read is never
//! lost. The card drives IRQ low while a pending bit is set that the host has not masked
//! (level, not edge); reply FLAGS bit 0 mirrors the line. **The mask** is `DRIVE.IRQ_MASK`
//! (bit set = that event does not assert IRQ; 0, the value of a host that never writes it,
//! masks nothing; taken while DRIVE is consistent). CARD changes on every card cycle (its
//! heartbeat) and STATUS with every bus event, so a host that runs the CYCLIC exchange every
//! cycle typically masks bits 1, 2, 5 and 10 (`0x0426`) and keeps IRQ for MBX_REQ: the line
//! then means "a parameter request is waiting". The IRQ pin floats during reset and start-up
//! (the host's pull-up reads "no events"), then is driven push-pull.
//!
//! **One drive cycle** (what [`SpiHost::cyclic`] does, under `dpm::host::Host::cycle`): a
//! CYCLIC request every drive cycle, clocked as long as the longer of it and the expected
//! reply; its MISO is the reply to the previous cycle's CYCLIC request, which the card
//! rebuilt from the image after each of its steps while it was armed (so it carries the
//! newest command). One transaction per drive cycle; when the MISO holds no reply to take
//! (the first cycle, a block access came between, a late or damaged reply) the same request
//! is sent once more, whose MISO is the reply to the first: two at most. The parameter
//! mailbox rides along (the reference hosts), in the bytes the telegram leaves of a 64-byte
//! transaction each way (the host's budget; ST1 leaves 22 reply / 29 request bytes, PPO 5
//! 6 / 9; at least 4, at most 32 bytes a fragment), one fragment each way per cycle. MBX_REQ:
//! when the reply's events show it changed, the next request asks its fragment from offset 0
//! (carrying SEQ_HEAD: the host's read of the block for the events), the next ones the
//! following bytes up to the end of its values; a request that took more than one fragment
//! is taken once a 2-byte fragment at SEQ_TAIL equals the head (each fragment is sent only
//! while the block is consistent, and the counter only grows, so every fragment between
//! came from that request); a reply whose events show MBX_REQ changed again restarts it at
//! offset 0. MBX_RSP: the answer's head, fields and values in ascending fragments, one per
//! cycle; a fragment counts as applied once the reply **to the request that carried it**
//! came back OK (one-transaction cycle: the reply answers the previous cycle's request; two
//! transactions: this cycle's), after a failed exchange the unconfirmed part goes again, and
//! the tail, which makes the block consistent, goes only once everything before it is
//! confirmed — so the card never takes a block with a stale middle. No block access. The
//! CYCLIC grammar follows at the end of this document.
//!
//! **A host access** (what [`SpiHost`] does): the request in one transaction, and in the
//! next a STATUS request padded to the expected reply, whose MISO is the reply; anything
//! but the echoing reply sends the request again (three retries).

use super::host::{CyclicReceipt, Transport, TransportError};
use super::layout::{self, Writer, BLOCKS, SPANS};
use super::{Dpm, IMAGE_SIZE};
pub use pipeline::{PipelineStats, ReplyPipeline};
pub use wire::WireImage;

/// Protocol version, first byte of the STATUS data.
pub const PROTOCOL_VERSION: u8 = 2;
/// Most data bytes one READ or WRITE moves.
pub const MAX_DATA: usize = 1024;
/// Request header: CMD, TAG, ADDR, LEN.
pub const REQUEST_HEADER: usize = 6;
/// Reply header: RESULT, TAG, CMD, FLAGS, ADDR, LEN.
pub const REPLY_HEADER: usize = 8;
/// The CRC at the end of each frame.
pub const CRC_LEN: usize = 2;
/// The longest request frame (a WRITE of [`MAX_DATA`] bytes).
pub const MAX_REQUEST: usize = REQUEST_HEADER + MAX_DATA + CRC_LEN;
/// The longest reply frame (a READ of [`MAX_DATA`] bytes).
pub const MAX_REPLY: usize = REPLY_HEADER + MAX_DATA + CRC_LEN;
/// The longest transaction the card takes (a longer one is refused as BAD_LENGTH).
pub const MAX_TRANSACTION: usize = if MAX_REPLY > MAX_REQUEST { MAX_REPLY } else { MAX_REQUEST };
/// Bytes of STATUS data.
pub const STATUS_LEN: usize = 20;
/// Offsets in the STATUS data (the module docs, "STATUS data").
pub mod status_data {
    /// u8 [`super::PROTOCOL_VERSION`].
    pub const VERSION: usize = 0;
    /// u16 [`super::MAX_DATA`].
    pub const MAX_DATA: usize = 2;
    /// u16 the image size.
    pub const IMAGE_SIZE: usize = 4;
    /// u16 the pending-events bitmap.
    pub const EVENTS: usize = 6;
    /// u16 × 6 counters: frames accepted, CRC errors, bad command, bad length, bad address,
    /// forbidden writes.
    pub const COUNTERS: usize = 8;
}
/// Time the master leaves the card between two transactions (typical; see the module docs).
pub const T_READY_US: u32 = 200;
/// Reply byte 0 when the card had no reply ready for this transaction.
pub const NO_REPLY: u8 = 0x00;
/// Reply FLAGS bit 0: events pending (IRQ asserted).
pub const FLAG_EVENTS: u8 = 1 << 0;
/// Bytes of DATA in the reply to an accepted WRITE: the request's CRC, so the host can tell
/// the reply to its own WRITE from any other (a stale one after a restart).
pub const WRITE_ECHO_LEN: usize = 2;

/// Indices in `layout::BLOCKS` of the blocks a CYCLIC reply carries.
const CARD_BLOCK: usize = 5;
const OUTPUTS_BLOCK: usize = 2;
const DRIVE_CMD_BLOCK: usize = 10;

const _: () = {
    assert!(BLOCKS[CARD_BLOCK].start == layout::card::START);
    assert!(BLOCKS[OUTPUTS_BLOCK].start == layout::outputs::START);
    assert!(BLOCKS[DRIVE_CMD_BLOCK].start == layout::drive_cmd::START);
    assert!(BLOCKS.len() <= 16, "the events bitmap is a u16");
    assert!(MAX_DATA <= u16::MAX as usize);
    assert!(IMAGE_SIZE <= u16::MAX as usize);
    assert!(REPLY_HEADER + STATUS_LEN + CRC_LEN <= MAX_TRANSACTION);
};

/// A request's CMD byte (the codes are at least 3 bits apart, and neither `0x00` nor `0xFF`,
/// which a floating or stuck line produces).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum Command {
    /// Read LEN bytes of the image from ADDR.
    Read = 0xA1,
    /// Write the DATA to the image at ADDR (host-written blocks only).
    Write = 0xB2,
    /// The card's protocol status and counters; also the "poll" that fetches a reply.
    Status = 0xC4,
    /// One drive cycle's exchange (protocol version 2, [`cyclic`]).
    Cyclic = 0xD8,
}

impl Command {
    /// The command of a CMD byte.
    pub const fn from_code(code: u8) -> Option<Command> {
        match code {
            0xA1 => Some(Command::Read),
            0xB2 => Some(Command::Write),
            0xC4 => Some(Command::Status),
            0xD8 => Some(Command::Cyclic),
            _ => None,
        }
    }

    /// Bytes of DATA a request with `len` in its LEN field carries.
    pub const fn data_len(self, len: u16) -> usize {
        match self {
            Command::Write | Command::Cyclic => len as usize,
            Command::Read | Command::Status => 0,
        }
    }
}

/// A reply's RESULT byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum ResultCode {
    /// Done: READ data / WRITE applied / STATUS data.
    Ok = 0x80,
    /// The request's CRC did not match: nothing done.
    CrcError = 0x81,
    /// CMD is not a [`Command`].
    BadCommand = 0x82,
    /// The transaction was shorter than the frame, longer than [`MAX_TRANSACTION`], its
    /// padding was not zero, or LEN was 0 / above [`MAX_DATA`].
    BadLength = 0x83,
    /// ADDR + LEN is beyond the image.
    BadAddress = 0x84,
    /// A WRITE touched a block the card writes.
    ForbiddenWrite = 0x85,
}

impl ResultCode {
    /// Every code.
    pub const ALL: [ResultCode; 6] = [
        ResultCode::Ok,
        ResultCode::CrcError,
        ResultCode::BadCommand,
        ResultCode::BadLength,
        ResultCode::BadAddress,
        ResultCode::ForbiddenWrite,
    ];

    /// Whether a damaged line can cause this refusal of a well-formed request (CRC error,
    /// a LEN or CMD bit flipped, a cut transaction): the master repeats the request. BAD_ADDRESS
    /// and FORBIDDEN_WRITE are decided on CRC-checked content and are final.
    pub const fn line_error(self) -> bool {
        matches!(self, ResultCode::CrcError | ResultCode::BadLength | ResultCode::BadCommand)
    }

    /// The code of a RESULT byte.
    pub fn from_code(code: u8) -> Option<ResultCode> {
        ResultCode::ALL.into_iter().find(|r| *r as u8 == code)
    }
}

/// The frame CRC: CRC-16/CCITT-FALSE, catalogued as CRC-16/IBM-3740 (polynomial 0x1021,
/// init 0xFFFF, no reflection, no final XOR, check 0x29B1), from the `crc` crate's
/// table-driven implementation, one table of 256 entries (512 B of flash; slice-by-16 took
/// 8 KiB, issue 13 item 1). Its cost: one table step a byte, about 8 instructions (≈ 10
/// cycles from flash), so the longest frame (1034 B) takes ≈ 0.1 ms at 96 MHz. A transaction
/// has one such CRC (a long WRITE's request or a long READ's reply), inside the 200 µs the
/// master leaves the card between two transactions (`docs/SPI.md`; an estimate, not measured
/// on hardware). The bitwise `NoTable` (eight steps a byte, ≈ 0.4 ms) would not fit. The
/// simulated drive's in-process frames pay it at both ends, in the unlocked part of the
/// bench's step (QEMU bench: 57 125 → 59 433 instructions).
static CRC: crc::Crc<u16, crc::Table<1>> = crc::Crc::<u16, crc::Table<1>>::new(&crc::CRC_16_IBM_3740);

/// CRC-16/CCITT-FALSE of `data`: polynomial 0x1021, init 0xFFFF, no reflection, no final
/// XOR (check value 0x29B1 for "123456789").
#[inline(never)]
pub fn crc16(data: &[u8]) -> u16 {
    CRC.checksum(data)
}

/// Continue a CRC-16/CCITT-FALSE over more bytes (`crc` = the value over the bytes before).
#[inline(never)]
pub fn crc16_update(crc: u16, data: &[u8]) -> u16 {
    let mut d = CRC.digest_with_initial(crc);
    d.update(data);
    d.finalize()
}

fn get16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn put16(b: &mut [u8], at: usize, v: u16) {
    b[at..at + 2].copy_from_slice(&v.to_be_bytes());
}

/// The card's protocol counters (all wrap). The STATUS data shows their low 16 bits.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct SpiStats {
    /// Frames accepted (RESULT OK).
    pub frames_ok: u32,
    /// Frames refused for their CRC.
    pub crc_errors: u32,
    /// Frames refused for an unknown CMD.
    pub bad_command: u32,
    /// Frames refused for their length (cut, overlong, padding, LEN).
    pub bad_length: u32,
    /// Frames refused because ADDR + LEN is beyond the image.
    pub bad_address: u32,
    /// WRITEs refused because they touched a card-written block.
    pub forbidden_writes: u32,
}

impl SpiStats {
    fn count(&mut self, r: ResultCode) {
        let c = match r {
            ResultCode::Ok => &mut self.frames_ok,
            ResultCode::CrcError => &mut self.crc_errors,
            ResultCode::BadCommand => &mut self.bad_command,
            ResultCode::BadLength => &mut self.bad_length,
            ResultCode::BadAddress => &mut self.bad_address,
            ResultCode::ForbiddenWrite => &mut self.forbidden_writes,
        };
        *c = c.wrapping_add(1);
    }

    /// Frames refused, all causes.
    pub fn refused(&self) -> u32 {
        self.crc_errors
            .wrapping_add(self.bad_command)
            .wrapping_add(self.bad_length)
            .wrapping_add(self.bad_address)
            .wrapping_add(self.forbidden_writes)
    }
}

/// A request that passed every check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Request<'a> {
    /// The command.
    pub cmd: Command,
    /// TAG.
    pub tag: u8,
    /// ADDR.
    pub addr: u16,
    /// LEN.
    pub len: u16,
    /// WRITE data (empty otherwise).
    pub data: &'a [u8],
    /// The frame's CRC (a WRITE's reply echoes it).
    pub crc: u16,
}

/// Why a transaction was refused, with what could be read of its header (for the reply's
/// echo fields; 0 where the transaction was too short).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Refusal {
    /// The RESULT sent.
    pub result: ResultCode,
    /// CMD byte as received.
    pub cmd: u8,
    /// TAG as received.
    pub tag: u8,
    /// ADDR as received.
    pub addr: u16,
}

/// Check one received transaction (MOSI bytes between NSS falling and rising) against the
/// grammar and the image: every check of the module docs, in that order. Pure: the image is
/// not touched.
pub fn parse_request(rx: &[u8]) -> Result<Request<'_>, Refusal> {
    let at = |i: usize| rx.get(i).copied().unwrap_or(0);
    let refuse = |result| Refusal { result, cmd: at(0), tag: at(1), addr: u16::from_be_bytes([at(2), at(3)]) };
    if rx.len() < REQUEST_HEADER + CRC_LEN || rx.len() > MAX_TRANSACTION {
        return Err(refuse(ResultCode::BadLength));
    }
    let (addr, len) = (get16(rx, 2), get16(rx, 4));
    // Unknown commands are framed as a header + CRC (no data): that is the only length
    // their CRC can be checked at.
    let cmd = Command::from_code(rx[0]);
    let data_len = cmd.map_or(0, |c| c.data_len(len));
    let frame = REQUEST_HEADER + data_len + CRC_LEN;
    if rx.len() < frame {
        return Err(refuse(ResultCode::BadLength));
    }
    if crc16(&rx[..frame - CRC_LEN]) != get16(rx, frame - CRC_LEN) {
        return Err(refuse(ResultCode::CrcError));
    }
    if !all_zero(&rx[frame..]) {
        return Err(refuse(ResultCode::BadLength));
    }
    let Some(cmd) = cmd else {
        return Err(refuse(ResultCode::BadCommand));
    };
    let n = usize::from(len);
    match cmd {
        Command::Status if addr != 0 || len != 0 => return Err(refuse(ResultCode::BadLength)),
        Command::Status => {}
        Command::Cyclic => {
            let data = &rx[REQUEST_HEADER..REQUEST_HEADER + data_len];
            if addr != 0 || cyclic::CyclicRequest::parse(data).is_none() {
                return Err(refuse(ResultCode::BadLength));
            }
        }
        Command::Read | Command::Write => {
            if n == 0 || n > MAX_DATA {
                return Err(refuse(ResultCode::BadLength));
            }
            if usize::from(addr) + n > IMAGE_SIZE {
                return Err(refuse(ResultCode::BadAddress));
            }
            if cmd == Command::Write && !host_writable(usize::from(addr), n) {
                return Err(refuse(ResultCode::ForbiddenWrite));
            }
        }
    }
    Ok(Request {
        cmd,
        tag: rx[1],
        addr,
        len,
        data: &rx[REQUEST_HEADER..REQUEST_HEADER + data_len],
        crc: get16(rx, frame - CRC_LEN),
    })
}

/// Whether `b` is all `0x00` (the padding check: four bytes per step).
fn all_zero(b: &[u8]) -> bool {
    let mut words = b.chunks_exact(4);
    words.by_ref().all(|w| u32::from_ne_bytes([w[0], w[1], w[2], w[3]]) == 0)
        && words.remainder().iter().all(|&x| x == 0)
}

/// Whether every byte of `start..start + len` lies in a block the host writes.
pub fn host_writable(start: usize, len: usize) -> bool {
    let end = start + len;
    let mut p = start;
    while p < end {
        match SPANS.iter().find(|b| p >= b.start && p < b.start + b.len) {
            Some(b) if b.writer == Writer::Host => p = b.start + b.len,
            _ => return false,
        }
    }
    true
}

/// The host's IRQ mask, `DRIVE.IRQ_MASK` (0 while DRIVE is not consistent).
pub fn irq_mask(dpm: &Dpm) -> u16 {
    let img = dpm.as_bytes();
    let (start, len) = (layout::drive::START, layout::drive::LEN);
    let head = get16(img, start);
    if head != 0 && head == get16(img, start + len - 2) {
        get16(img, start + layout::drive::IRQ_MASK)
    } else {
        0
    }
}

/// Bits of the events bitmap that can be set: the sequenced blocks the card writes.
pub const EVENT_BLOCKS: u16 = {
    let mut m = 0u16;
    let mut i = 0;
    while i < BLOCKS.len() {
        if BLOCKS[i].sequenced && matches!(BLOCKS[i].writer, Writer::Card) {
            m |= 1 << i;
        }
        i += 1;
    }
    m
};

/// The card side of the SPI transport: takes one transaction's MOSI bytes, checks them,
/// applies an accepted WRITE to the image, and builds the reply for the next transaction.
/// Also keeps the pending-events bitmap that drives the IRQ line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SpiSlave {
    stats: SpiStats,
    /// The last accepted request was CYCLIC: its TAG and the MBX_REQ fragment it asked for
    /// (the armed reply is refreshed from them).
    cyclic: Option<(u8, (u8, u8))>,
    /// Per block: the `SEQ_HEAD` value the host last read (0 = never read).
    host_seen: [u16; BLOCKS.len()],
}

impl Default for SpiSlave {
    fn default() -> Self {
        Self::new()
    }
}

impl SpiSlave {
    /// No frame seen yet; every card block written since the image was created is pending.
    pub const fn new() -> Self {
        SpiSlave {
            stats: SpiStats {
                frames_ok: 0,
                crc_errors: 0,
                bad_command: 0,
                bad_length: 0,
                bad_address: 0,
                forbidden_writes: 0,
            },
            cyclic: None,
            host_seen: [0; BLOCKS.len()],
        }
    }

    /// The counters.
    pub fn stats(&self) -> SpiStats {
        self.stats
    }

    /// The pending-events bitmap: bit i = `BLOCKS[i]` changed since the host last read its
    /// `SEQ_HEAD`.
    ///
    /// Out of line: several tasks call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub fn events(&self, dpm: &Dpm) -> u16 {
        let img = dpm.as_bytes();
        let mut m = 0;
        for (i, b) in SPANS.iter().enumerate() {
            if EVENT_BLOCKS & (1 << i) != 0 && get16(img, b.start) != self.host_seen[i] {
                m |= 1 << i;
            }
        }
        m
    }

    /// The IRQ line: asserted while any event is pending that the host's `DRIVE.IRQ_MASK`
    /// does not mask.
    pub fn irq(&self, dpm: &Dpm) -> bool {
        self.events(dpm) & !irq_mask(dpm) != 0
    }

    /// Handle one transaction: `rx` is every MOSI byte between NSS falling and rising. An
    /// accepted WRITE is applied to `dpm`; the reply (to be clocked out in the next
    /// transaction, followed by `0x00` padding) is written to the start of `reply`. Returns
    /// the reply's length. Never panics, whatever `rx` holds.
    pub fn handle(&mut self, rx: &[u8], dpm: &mut Dpm, reply: &mut [u8; MAX_REPLY]) -> usize {
        self.cyclic = None;
        let (result, cmd, tag, addr, n) = match parse_request(rx) {
            Ok(req) => {
                let n = match req.cmd {
                    Command::Read => {
                        let (a, n) = (usize::from(req.addr), usize::from(req.len));
                        reply[REPLY_HEADER..REPLY_HEADER + n].copy_from_slice(&dpm.as_bytes()[a..a + n]);
                        self.note_read(dpm, a, n);
                        n
                    }
                    Command::Write => {
                        let a = usize::from(req.addr);
                        dpm.as_bytes_mut()[a..a + req.data.len()].copy_from_slice(req.data);
                        put16(reply, REPLY_HEADER, req.crc);
                        WRITE_ECHO_LEN
                    }
                    Command::Status => STATUS_LEN,
                    Command::Cyclic => match cyclic::CyclicRequest::parse(req.data) {
                        Some(c) => {
                            c.apply(dpm);
                            self.cyclic = Some((req.tag, c.req));
                            self.cyclic_data(dpm, c.req, reply)
                        }
                        // `parse_request` checked it.
                        None => 0,
                    },
                };
                self.stats.count(ResultCode::Ok);
                if req.cmd == Command::Status {
                    self.status_data(dpm, &mut reply[REPLY_HEADER..REPLY_HEADER + STATUS_LEN]);
                }
                (ResultCode::Ok, req.cmd as u8, req.tag, req.addr, n)
            }
            Err(r) => {
                self.stats.count(r.result);
                (r.result, r.cmd, r.tag, r.addr, 0)
            }
        };
        self.finish(dpm, reply, (result, cmd, tag, addr), n)
    }

    /// The reply header and CRC around `n` bytes of DATA already in place.
    #[inline(never)]
    fn finish(&self, dpm: &Dpm, reply: &mut [u8; MAX_REPLY], head: (ResultCode, u8, u8, u16), n: usize) -> usize {
        let (result, cmd, tag, addr) = head;
        reply[0] = result as u8;
        reply[1] = tag;
        reply[2] = cmd;
        reply[3] = if self.irq(dpm) { FLAG_EVENTS } else { 0 };
        put16(reply, 4, addr);
        put16(reply, 6, n as u16);
        let end = REPLY_HEADER + n;
        let crc = crc16(&reply[..end]);
        put16(reply, end, crc);
        end + CRC_LEN
    }

    /// The CYCLIC reply DATA from the image as it is now; the blocks it carries (CARD,
    /// OUTPUTS, DRIVE_CMD: the command names its outputs) count as read for the events.
    fn cyclic_data(&mut self, dpm: &Dpm, req: (u8, u8), reply: &mut [u8; MAX_REPLY]) -> usize {
        for b in [&SPANS[CARD_BLOCK], &SPANS[OUTPUTS_BLOCK], &SPANS[DRIVE_CMD_BLOCK]] {
            self.note_read(dpm, b.start, 2);
        }
        // An MBX_REQ fragment from offset 0 carries its SEQ_HEAD (sent only while the block
        // is consistent): it counts as a read of the block.
        let img = dpm.as_bytes();
        let (start, len) = (layout::mbx_req::START, layout::mbx_req::LEN);
        let head = get16(img, start);
        if req.0 == 0 && req.1 >= 2 && head != 0 && head == get16(img, start + len - 2) {
            self.note_read(dpm, start, 2);
        }
        let events = self.events(dpm);
        cyclic::build_reply(dpm, events, req, &mut reply[REPLY_HEADER..])
    }

    /// Rebuild an armed reply with the image as it is now, if it answers a request whose
    /// reply carries live data (a CYCLIC exchange): returns its new length. `None`: the reply
    /// stays as built (READ / WRITE / STATUS replies are the image at request time).
    pub fn refresh(&mut self, dpm: &Dpm, reply: &mut [u8; MAX_REPLY]) -> Option<usize> {
        let (tag, req) = self.cyclic?;
        let n = self.cyclic_data(dpm, req, reply);
        Some(self.finish(dpm, reply, (ResultCode::Ok, Command::Cyclic as u8, tag, 0), n))
    }

    /// An accepted READ of `a..a + n` clears the events of the blocks whose `SEQ_HEAD` it
    /// covers.
    ///
    /// Out of line: several tasks call it (footprint, issue 13 item 1).
    #[inline(never)]
    fn note_read(&mut self, dpm: &Dpm, a: usize, n: usize) {
        for (i, b) in SPANS.iter().enumerate() {
            if EVENT_BLOCKS & (1 << i) != 0 && b.start >= a && b.start + 2 <= a + n {
                self.host_seen[i] = get16(dpm.as_bytes(), b.start);
            }
        }
    }

    fn status_data(&self, dpm: &Dpm, d: &mut [u8]) {
        let s = &self.stats;
        d[status_data::VERSION] = PROTOCOL_VERSION;
        d[status_data::VERSION + 1] = 0;
        put16(d, status_data::MAX_DATA, MAX_DATA as u16);
        put16(d, status_data::IMAGE_SIZE, IMAGE_SIZE as u16);
        put16(d, status_data::EVENTS, self.events(dpm));
        for (i, c) in [s.frames_ok, s.crc_errors, s.bad_command, s.bad_length, s.bad_address, s.forbidden_writes]
            .into_iter()
            .enumerate()
        {
            put16(d, status_data::COUNTERS + 2 * i, c as u16);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Host side
// ---------------------------------------------------------------------------------------------

/// A decoded reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reply<'a> {
    /// RESULT.
    pub result: ResultCode,
    /// TAG.
    pub tag: u8,
    /// CMD byte.
    pub cmd: u8,
    /// FLAGS ([`FLAG_EVENTS`]).
    pub flags: u8,
    /// ADDR.
    pub addr: u16,
    /// DATA (READ: image bytes; STATUS: [`StatusData`] bytes).
    pub data: &'a [u8],
}

/// Why MISO bytes are not a reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum ReplyError {
    /// First byte `0x00`: the card had no reply ready (poll again).
    NoReply,
    /// RESULT is no [`ResultCode`] (e.g. `0xFF`: no card, MISO floating high).
    BadResult(u8),
    /// Fewer bytes than the reply announces.
    Truncated,
    /// The reply's CRC does not match.
    Crc,
}

/// The STATUS data, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StatusData {
    /// [`PROTOCOL_VERSION`] of the card.
    pub version: u8,
    /// [`MAX_DATA`] of the card.
    pub max_data: u16,
    /// The image size.
    pub image_size: u16,
    /// The pending-events bitmap.
    pub events: u16,
    /// The card's counters (low 16 bits).
    pub stats: [u16; 6],
}

impl StatusData {
    /// Decode [`STATUS_LEN`] bytes (`None` if shorter).
    pub fn decode(d: &[u8]) -> Option<StatusData> {
        if d.len() < STATUS_LEN {
            return None;
        }
        let mut stats = [0u16; 6];
        for (i, s) in stats.iter_mut().enumerate() {
            *s = get16(d, status_data::COUNTERS + 2 * i);
        }
        Some(StatusData {
            version: d[status_data::VERSION],
            max_data: get16(d, status_data::MAX_DATA),
            image_size: get16(d, status_data::IMAGE_SIZE),
            events: get16(d, status_data::EVENTS),
            stats,
        })
    }
}

/// The host's frame encoder and reply decoder: what a drive maker ports (it needs nothing
/// but [`crc16`]). It hands out the TAGs.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SpiHostCodec {
    next_tag: u8,
}

impl SpiHostCodec {
    /// TAGs start at 0.
    pub const fn new() -> Self {
        SpiHostCodec { next_tag: 0 }
    }

    /// Encode a request into `out` (zero-padded to its end): returns (TAG, frame length).
    /// `data` is sent for WRITE only; for READ, `len` is the bytes wanted. `None` if `out`
    /// is too short for the frame.
    pub fn encode(&mut self, cmd: Command, addr: u16, len: u16, data: &[u8], out: &mut [u8]) -> Option<(u8, usize)> {
        let data = if matches!(cmd, Command::Write | Command::Cyclic) { data } else { &[] };
        let n = REQUEST_HEADER + data.len() + CRC_LEN;
        if out.len() < n {
            return None;
        }
        let tag = self.next_tag;
        self.next_tag = self.next_tag.wrapping_add(1);
        out[0] = cmd as u8;
        out[1] = tag;
        put16(out, 2, addr);
        put16(out, 4, len);
        out[REQUEST_HEADER..REQUEST_HEADER + data.len()].copy_from_slice(data);
        let crc = crc16(&out[..n - CRC_LEN]);
        put16(out, n - CRC_LEN, crc);
        out[n..].fill(0);
        Some((tag, n))
    }

    /// Decode the MISO bytes of a transaction.
    pub fn decode(miso: &[u8]) -> Result<Reply<'_>, ReplyError> {
        match miso.first() {
            None => return Err(ReplyError::Truncated),
            Some(&NO_REPLY) => return Err(ReplyError::NoReply),
            Some(_) => {}
        }
        let result = ResultCode::from_code(miso[0]).ok_or(ReplyError::BadResult(miso[0]))?;
        if miso.len() < REPLY_HEADER + CRC_LEN {
            return Err(ReplyError::Truncated);
        }
        let n = usize::from(get16(miso, 6));
        let end = REPLY_HEADER + n;
        if miso.len() < end + CRC_LEN {
            return Err(ReplyError::Truncated);
        }
        if crc16(&miso[..end]) != get16(miso, end) {
            return Err(ReplyError::Crc);
        }
        Ok(Reply {
            result,
            tag: miso[1],
            cmd: miso[2],
            flags: miso[3],
            addr: get16(miso, 4),
            data: &miso[REPLY_HEADER..end],
        })
    }
}

/// The SPI bus, as the host's SPI master driver offers it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct BusFault;

/// One full-duplex transaction: NSS low, `mosi.len()` bytes out while as many come in on
/// `miso` (same length), NSS high.
pub trait SpiBus {
    /// Run one transaction.
    fn transfer(&mut self, mosi: &[u8], miso: &mut [u8]) -> Result<(), BusFault>;
}

/// The card's end of the DPM SPI link — the board contract of the DPM transport (issue 13
/// item 3; README "Hardware"): the board's SPI slave peripheral with its DMA buffers, its
/// reply pipeline ([`ReplyPipeline`]) and the IRQ line to the host. The protocol is
/// [`WireImage::handle`]'s; the port only moves the bytes (`docs/SPI.md`).
///
/// No method waits for the bus. On the F411 (`crates/bsp/src/spi.rs`) [`on_nss_rise`](SlavePort::on_nss_rise)
/// runs in the NSS interrupt (priority 12), the frame task (11) takes a reply buffer, arms the
/// reply and gives the frame back, and [`set_irq`](SlavePort::set_irq) runs there and in the
/// 1 ms IRQ task. A platform whose transport is in process (QEMU, the soft slave:
/// [`Loopback`]) has no port.
pub trait SlavePort {
    /// One received transaction, lent by the port until [`give_back`](SlavePort::give_back)
    /// or [`drop_frame`](SlavePort::drop_frame): its MOSI bytes.
    type Frame: AsRef<[u8]>;
    /// A reply buffer lent by the port ([`MAX_REPLY`] bytes).
    type Reply: AsMut<[u8]>;

    /// A transaction ended (NSS rose): re-arm the receiver for the next one and return what
    /// was received — `None` for an empty transaction or when the frame task still holds the
    /// spare buffer (the transaction is dropped and counted).
    fn on_nss_rise(&mut self) -> Option<Self::Frame>;

    /// A buffer for the next reply (`None` when the frame task already holds every free one).
    fn reply_buffer(&mut self) -> Option<Self::Reply>;

    /// The reply in the first `len` bytes of `buf` (the rest is zeroed) goes out in the next
    /// transaction if that has not begun yet; else it is late and discarded (the host sees
    /// `0x00` and repeats its request). Returns whether it was armed.
    fn reply_ready(&mut self, buf: Self::Reply, len: usize) -> bool;

    /// The frame task is done with `frame`.
    fn give_back(&mut self, frame: Self::Frame);

    /// A received frame nobody could handle: counted dropped, its buffer taken back.
    fn drop_frame(&mut self, frame: Self::Frame);

    /// Drive the IRQ line to the host: `true` = asserted ([`WireImage::irq`]).
    fn set_irq(&mut self, asserted: bool);
}

/// Why a host access failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum HostError {
    /// The SPI driver failed.
    Bus,
    /// The card refused the request (a line-error refusal only after every retry).
    Refused(ResultCode),
    /// No valid reply with our TAG after every retry (no card, a card too busy, a line too
    /// noisy).
    NoReply,
    /// The request does not fit a frame (longer than [`MAX_DATA`] per piece is split; this
    /// is an empty access or one past `u16::MAX`).
    BadRequest,
}

/// The host side over any [`SpiBus`]: `read(offset, buf)` / `write(offset, data)` on the
/// card's image, split into frames of at most [`MAX_DATA`] bytes, each confirmed by its
/// reply, fetched in the next transaction (a STATUS request padded to the reply's length).
/// A reply is taken only when it echoes the request: TAG, CMD, ADDR, and the data length
/// asked (a WRITE: the request's CRC); anything else — `0x00` (the card was late), a stale
/// reply, a damaged one, a line-error refusal — sends the request again, up to the retries.
#[derive(Debug, Clone)]
pub struct SpiHost<B: SpiBus> {
    bus: B,
    codec: SpiHostCodec,
    mosi: [u8; MAX_TRANSACTION],
    miso: [u8; MAX_TRANSACTION],
    /// Requests sent again after a lost or corrupted reply.
    retries: u8,
    last_flags: u8,
    retried: u32,
    transactions: u32,
    bytes: u32,
    /// The TAG of the CYCLIC request sent in the last transaction (its reply comes in the
    /// next one: the next cycle's CYCLIC request fetches it).
    cyclic_pending: Option<u8>,
    /// MBX_REQ fragment bytes the pending CYCLIC request asked (its reply is that much longer).
    cyclic_asked: usize,
    /// DATA bytes of the last CYCLIC reply without its MBX_REQ fragment (the next
    /// transaction is clocked that long, plus the fragment asked).
    cyclic_reply_len: usize,
    /// The last CYCLIC reply taken answered the previous call's request.
    cyclic_previous: bool,
}

impl<B: SpiBus> SpiHost<B> {
    /// Three retries.
    pub fn new(bus: B) -> Self {
        SpiHost {
            bus,
            codec: SpiHostCodec::new(),
            mosi: [0; MAX_TRANSACTION],
            miso: [0; MAX_TRANSACTION],
            retries: 3,
            last_flags: 0,
            retried: 0,
            transactions: 0,
            bytes: 0,
            cyclic_pending: None,
            cyclic_asked: 0,
            cyclic_reply_len: cyclic::MAX_REPLY_DATA - cyclic::MAX_FRAGMENT,
            cyclic_previous: false,
        }
    }

    /// One drive cycle's CYCLIC exchange: sends `req` and returns a CYCLIC reply's DATA
    /// ([`cyclic::CyclicReply::decode`]). In the steady state this is **one** transaction: its
    /// MISO is the reply to the previous cycle's CYCLIC request, which the card refreshed
    /// after its last step (the newest command). When there is none to take (the first
    /// cycle, a block access came between, the reply was late or damaged) a second
    /// transaction (the same request again) fetches the reply to this one. Never more: a failure is
    /// returned, and the next cycle tries again (the reference host never blocks its cycle).
    pub fn cyclic(&mut self, req: &cyclic::CyclicRequest<'_>) -> Result<&[u8], HostError> {
        let prev = self.cyclic_pending.take();
        let mut d = [0u8; cyclic::MAX_REQUEST_DATA];
        if req.len() > d.len() {
            return Err(HostError::BadRequest);
        }
        let k = req.encode(&mut d);
        let frame = REQUEST_HEADER + k + CRC_LEN;
        let asked = core::mem::replace(&mut self.cyclic_asked, usize::from(req.req.1));
        // Clocked as long as the reply expected: the last one's length (without its
        // fragment) and the fragment the answered request asked.
        let expect = |len: usize, asked: usize| (REPLY_HEADER + len + asked + CRC_LEN).min(MAX_TRANSACTION);
        let n = if prev.is_some() { frame.max(expect(self.cyclic_reply_len, asked)) } else { frame };
        let (tag, _) = self
            .codec
            .encode(Command::Cyclic, 0, k as u16, &d[..k], &mut self.mosi[..n])
            .ok_or(HostError::BadRequest)?;
        self.transfer(n)?;
        if let Some(ptag) = prev {
            if let Some(r) = self.cyclic_reply(ptag, n) {
                self.cyclic_pending = Some(tag);
                self.cyclic_previous = true;
                return Ok(&self.miso[REPLY_HEADER..REPLY_HEADER + r]);
            }
        }
        // Fetch the reply to this request with the same request once more, which starts the
        // chain for the next cycle; the card applies it again, with the same counters: no
        // change. Clocked for the longest command (the first attempt may have failed because
        // the command grew: a new telegram), plus the fragment asked.
        let n = frame.max(expect(cyclic::MAX_REPLY_DATA - cyclic::MAX_FRAGMENT, usize::from(req.req.1)));
        let (tag2, _) = self
            .codec
            .encode(Command::Cyclic, 0, k as u16, &d[..k], &mut self.mosi[..n])
            .ok_or(HostError::BadRequest)?;
        self.transfer(n)?;
        self.cyclic_previous = false;
        match self.cyclic_reply(tag, n) {
            Some(r) => {
                self.cyclic_pending = Some(tag2);
                Ok(&self.miso[REPLY_HEADER..REPLY_HEADER + r])
            }
            None => {
                self.cyclic_reply_len = cyclic::MAX_REPLY_DATA - cyclic::MAX_FRAGMENT;
                match SpiHostCodec::decode(&self.miso[..n]) {
                    Ok(r) if r.tag == tag && r.result != ResultCode::Ok => Err(HostError::Refused(r.result)),
                    _ => {
                        // Perhaps the reply to the repeated request comes next cycle.
                        self.cyclic_pending = Some(tag2);
                        Err(HostError::NoReply)
                    }
                }
            }
        }
    }

    /// Whether the reply the last successful [`Self::cyclic`] returned answers the request
    /// of the call before (one transaction: the board's pipeline) rather than that call's
    /// own (two transactions).
    pub fn cyclic_answered_previous(&self) -> bool {
        self.cyclic_previous
    }

    /// The CYCLIC reply tagged `tag` in the MISO of the last transaction (`n` bytes): its
    /// DATA length, or `None`.
    fn cyclic_reply(&mut self, tag: u8, n: usize) -> Option<usize> {
        let r = SpiHostCodec::decode(&self.miso[..n]).ok()?;
        self.last_flags = r.flags;
        let ok = r.tag == tag
            && r.cmd == Command::Cyclic as u8
            && r.result == ResultCode::Ok
            && r.addr == 0
            && cyclic::CyclicReply::decode(r.data).is_some();
        if !ok {
            return None;
        }
        // Without its MBX_REQ fragment (the next request says how long that is).
        self.cyclic_reply_len = r.data.len() - usize::from(r.data[cyclic::rep::REQ_LEN]);
        Some(r.data.len())
    }

    /// The bus (the loopback card, for a test).
    pub fn bus(&self) -> &B {
        &self.bus
    }

    /// The bus, mutable.
    pub fn bus_mut(&mut self) -> &mut B {
        &mut self.bus
    }

    /// Give the bus back.
    pub fn into_bus(self) -> B {
        self.bus
    }

    /// Requests sent again so far.
    pub fn retried(&self) -> u32 {
        self.retried
    }

    /// Transactions run so far, and the bytes clocked in them (each byte one SCK octet,
    /// both directions at once).
    pub fn traffic(&self) -> (u32, u32) {
        (self.transactions, self.bytes)
    }

    /// FLAGS of the last reply: [`FLAG_EVENTS`] = the card has pending events (IRQ).
    pub fn events_pending(&self) -> bool {
        self.last_flags & FLAG_EVENTS != 0
    }

    /// Read `buf.len()` bytes of the image from `offset`.
    pub fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), HostError> {
        check_range(offset, buf.len())?;
        for (i, chunk) in buf.chunks_mut(MAX_DATA).enumerate() {
            let at = offset + (i * MAX_DATA) as u16;
            let data = self.exchange(Command::Read, at, chunk.len() as u16, &[])?;
            // `exchange` checked the length against the one asked.
            chunk.copy_from_slice(data);
        }
        Ok(())
    }

    /// Write `data` to the image at `offset` (host-written blocks only).
    pub fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), HostError> {
        check_range(offset, data.len())?;
        for (i, chunk) in data.chunks(MAX_DATA).enumerate() {
            let at = offset + (i * MAX_DATA) as u16;
            self.exchange(Command::Write, at, chunk.len() as u16, chunk)?;
        }
        Ok(())
    }

    /// The card's STATUS data.
    pub fn status(&mut self) -> Result<StatusData, HostError> {
        let d = self.exchange(Command::Status, 0, 0, &[])?;
        StatusData::decode(d).ok_or(HostError::NoReply)
    }

    /// One full-duplex transaction of `n` bytes from `self.mosi` (counted).
    pub(crate) fn transfer(&mut self, n: usize) -> Result<(), HostError> {
        self.transactions = self.transactions.wrapping_add(1);
        self.bytes = self.bytes.wrapping_add(n as u32);
        self.bus.transfer(&self.mosi[..n], &mut self.miso[..n]).map_err(|_| HostError::Bus)
    }

    /// One request and its reply's data (in `self.miso`).
    fn exchange(&mut self, cmd: Command, addr: u16, len: u16, data: &[u8]) -> Result<&[u8], HostError> {
        let n_data = match cmd {
            Command::Read => usize::from(len),
            Command::Status => STATUS_LEN,
            Command::Write => WRITE_ECHO_LEN,
            // One per drive cycle, through `cyclic`.
            Command::Cyclic => return Err(HostError::BadRequest),
        };
        self.cyclic_pending = None;
        let want = REPLY_HEADER + n_data + CRC_LEN;
        let mut last = HostError::NoReply;
        for attempt in 0..=self.retries {
            if attempt > 0 {
                self.retried = self.retried.wrapping_add(1);
            }
            // Encode into the frame's own length: the zero padding of `encode` then costs
            // nothing (the buffer holds the longest transaction).
            let frame = REQUEST_HEADER + if cmd == Command::Write { data.len() } else { 0 } + CRC_LEN;
            let out = self.mosi.get_mut(..frame).ok_or(HostError::BadRequest)?;
            let (tag, n) = self.codec.encode(cmd, addr, len, data, out).ok_or(HostError::BadRequest)?;
            let request_crc = get16(&self.mosi, n - CRC_LEN);
            self.transfer(n)?;
            // The next transaction fetches the reply: a STATUS request padded to it.
            let fetch = (REQUEST_HEADER + CRC_LEN).max(want).min(MAX_TRANSACTION);
            let out = &mut self.mosi[..fetch];
            self.codec.encode(Command::Status, 0, 0, &[], out).ok_or(HostError::BadRequest)?;
            self.transfer(fetch)?;
            let r = match SpiHostCodec::decode(&self.miso[..fetch]) {
                Ok(r) => r,
                // `0x00`: the card was late (or dropped the request); else a damaged reply.
                Err(_) => continue,
            };
            self.last_flags = r.flags;
            if r.tag != tag || r.cmd != cmd as u8 || r.addr != addr {
                // Not the reply to this request (a stale one): ask again.
                continue;
            }
            match r.result {
                ResultCode::Ok => {
                    let echo_ok = r.data.len() == n_data && (cmd != Command::Write || get16(r.data, 0) == request_crc);
                    if echo_ok {
                        return Ok(&self.miso[REPLY_HEADER..REPLY_HEADER + n_data]);
                    }
                }
                // Our (well-formed) request was damaged on the way: send it again.
                r if r.line_error() => last = HostError::Refused(r),
                r => return Err(HostError::Refused(r)),
            }
        }
        Err(last)
    }
}

fn check_range(offset: u16, len: usize) -> Result<(), HostError> {
    if len == 0 || usize::from(offset) + len > usize::from(u16::MAX) + 1 {
        Err(HostError::BadRequest)
    } else {
        Ok(())
    }
}

impl From<HostError> for TransportError {
    /// A bus fault or a card that never answered with our TAG is "no response"; a refusal
    /// for a line error (CRC, length, command) that outlived every retry is "corrupt";
    /// BAD_ADDRESS and a request that does not fit a frame are "out of range"; FORBIDDEN_WRITE
    /// is "refused".
    fn from(e: HostError) -> Self {
        match e {
            HostError::Bus | HostError::NoReply => TransportError::NoResponse,
            HostError::Refused(ResultCode::BadAddress) | HostError::BadRequest => TransportError::OutOfRange,
            HostError::Refused(ResultCode::ForbiddenWrite) => TransportError::Refused,
            HostError::Refused(_) => TransportError::Corrupt,
        }
    }
}

/// The SPI frames as the host reference implementation's transport
/// ([`crate::dpm::host::Host`] over [`SpiHost`]): each `read` / `write` is one or more
/// READ / WRITE frames of ascending addresses (the transport order rule), confirmed by their
/// replies.
impl<B: SpiBus> Transport for SpiHost<B> {
    fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError> {
        SpiHost::read(self, offset, buf).map_err(TransportError::from)
    }
    fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError> {
        SpiHost::write(self, offset, data).map_err(TransportError::from)
    }
    fn cyclic(
        &mut self,
        req: &cyclic::CyclicRequest<'_>,
        out: &mut [u8; cyclic::MAX_REPLY_DATA],
    ) -> Option<Result<CyclicReceipt, TransportError>> {
        Some(match SpiHost::cyclic(self, req) {
            Ok(d) if d.len() <= out.len() => {
                let len = d.len();
                out[..len].copy_from_slice(d);
                Ok(CyclicReceipt { len, previous: self.cyclic_previous })
            }
            Ok(_) => Err(TransportError::Corrupt),
            Err(e) => Err(e.into()),
        })
    }
}

impl SpiHost<Loopback> {
    /// The in-process card's image (what the card side reads between host calls).
    pub fn dpm(&self) -> &Dpm {
        self.bus.dpm()
    }

    /// The in-process card's image, for the card side's own writes between host calls.
    pub fn dpm_mut(&mut self) -> &mut Dpm {
        self.bus.dpm_mut()
    }
}

/// An in-process card behind an [`SpiBus`]: the image, an [`SpiSlave`], and the board's
/// reply pipeline ([`ReplyPipeline`], the same state machine `crates/bsp/src/spi.rs` runs): the reply
/// to transaction *k* goes out in *k + 1* or never. Fault injection models the board's two
/// ways of missing it: [`set_late`](Self::set_late) (the frame task finished after the next
/// NSS fall) and [`set_busy`](Self::set_busy) (the frame task still held the receive buffer).
/// For the QEMU build, the soft slave and the tests.
#[derive(Debug, Clone)]
pub struct Loopback {
    dpm: Dpm,
    slave: SpiSlave,
    replies: [[u8; MAX_REPLY]; 2],
    lens: [usize; 2],
    pipeline: ReplyPipeline<usize>,
    busy: u32,
    late: u32,
    dropped: u32,
}

impl Loopback {
    /// A card serving `dpm`, no reply pending.
    pub fn new(dpm: Dpm) -> Self {
        Loopback {
            dpm,
            slave: SpiSlave::new(),
            replies: [[0; MAX_REPLY]; 2],
            lens: [0; 2],
            pipeline: ReplyPipeline::new(0, 1),
            busy: 0,
            late: 0,
            dropped: 0,
        }
    }

    /// The image.
    pub fn dpm(&self) -> &Dpm {
        &self.dpm
    }

    /// The image, for the card's own writes.
    pub fn dpm_mut(&mut self) -> &mut Dpm {
        &mut self.dpm
    }

    /// The card's protocol state.
    pub fn slave(&self) -> &SpiSlave {
        &self.slave
    }

    /// The card's protocol state, writable (a test restarts it).
    pub fn slave_mut(&mut self) -> &mut SpiSlave {
        &mut self.slave
    }

    /// The reply pipeline's counters.
    pub fn pipeline(&self) -> PipelineStats {
        self.pipeline.stats()
    }

    /// The IRQ line (asserted = true).
    pub fn irq(&self) -> bool {
        self.slave.irq(&self.dpm)
    }

    /// Fault injection: the next `n` transactions find the card busy — MISO `0x00`, the
    /// request dropped, the reply armed for it lost (what the board does when its frame task
    /// has not returned the receive buffer yet).
    pub fn set_busy(&mut self, n: u32) {
        self.busy = n;
    }

    /// Fault injection: the replies to the next `n` transactions are late (built after the
    /// following transaction began): each is discarded, that transaction's MISO is `0x00`.
    pub fn set_late(&mut self, n: u32) {
        self.late = n;
    }

    /// Transactions dropped while busy.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }
}

impl SpiBus for Loopback {
    fn transfer(&mut self, mosi: &[u8], miso: &mut [u8]) -> Result<(), BusFault> {
        if mosi.len() != miso.len() {
            return Err(BusFault);
        }
        if self.busy > 0 {
            self.busy -= 1;
            self.dropped = self.dropped.wrapping_add(1);
            self.pipeline.discard();
            miso.fill(NO_REPLY);
            self.pipeline.transaction_end();
            return Ok(());
        }
        if mosi.is_empty() {
            // An NSS pulse without clocks: the board counts it and hands nothing on, but the
            // armed reply is gone.
            self.pipeline.transaction_end();
            return Ok(());
        }
        // The board rebuilds an armed CYCLIC reply after each card step (the image may have
        // changed since the request): the loopback does it when the transaction begins.
        if let Some(&i) = self.pipeline.armed() {
            if let Some(n) = self.slave.refresh(&self.dpm, &mut self.replies[i]) {
                self.lens[i] = n;
            }
        }
        match self.pipeline.armed() {
            Some(&i) => {
                let k = self.lens[i].min(miso.len());
                miso[..k].copy_from_slice(&self.replies[i][..k]);
                miso[k..].fill(0);
            }
            None => miso.fill(NO_REPLY),
        }
        self.pipeline.transaction_end();
        let Some(i) = self.pipeline.buffer() else { return Ok(()) };
        self.lens[i] = self.slave.handle(mosi, &mut self.dpm, &mut self.replies[i]);
        let idle = if self.late > 0 {
            self.late -= 1;
            false
        } else {
            true
        };
        self.pipeline.ready(i, idle);
        Ok(())
    }
}

pub mod cyclic;
pub mod pipeline;
pub mod wire;

#[cfg(test)]
mod tests;
