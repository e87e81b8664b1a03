//! The C header of the DPM interface (issue 16 item 5): `c-host/include/pbcard_dpm.h`, generated
//! from [`layout`] ([`layout::BLOCKS`], [`layout::FIELDS`], the capability bits) and the SPI
//! frame definitions of [`spi`] and [`cyclic`], so that a drive maker's C code uses the same
//! numbers as the card. A test fails when the committed header differs
//! (`dpm::c_header::tests::c_header_is_current`, regenerated like `docs/DPM.md`).

use super::layout::{self, cap, Writer, BLOCKS, FIELDS};
use super::spi::{self, cyclic, Command, ResultCode};
use core::fmt::{self, Write};

/// The C identifier of a layout name: upper case, `.` → `_`.
fn ident(out: &mut impl Write, name: &str) -> fmt::Result {
    for c in name.chars() {
        out.write_char(if c == '.' { '_' } else { c.to_ascii_uppercase() })?;
    }
    Ok(())
}

fn define(out: &mut impl Write, name: &str, value: impl fmt::Display, doc: &str) -> fmt::Result {
    let mut v = heapless::String::<24>::new();
    write!(v, "{value}")?;
    writeln!(out, "#define PBCARD_{name:<38} {v:<8} /* {doc} */")
}

/// Write the header (the content of `c-host/include/pbcard_dpm.h`).
pub fn write_c_header(out: &mut impl Write) -> fmt::Result {
    writeln!(out, "/* pbcard_dpm.h: the pbcard DPM image (docs/DPM.md) and its SPI frames (docs/SPI.md).")?;
    writeln!(out, " *")?;
    writeln!(out, " * Generated from crates/dpm/src/dpm/layout.rs, spi.rs and spi/cyclic.rs. Do not edit:")?;
    writeln!(out, " * DPM_DOC_WRITE=1 cargo test -p pbcard-dpm --lib --target x86_64-unknown-linux-gnu dpm::c_header")?;
    writeln!(out, " *")?;
    writeln!(out, " * Blocks: PBCARD_<BLOCK>_START (absolute) and _SIZE; PBCARD_<BLOCK>_<FIELD> is the offset")?;
    writeln!(out, " * inside the block, PBCARD_<BLOCK>_<FIELD>_ADDR the absolute one, _SIZE its bytes. Every")?;
    writeln!(out, " * multi-byte integer is big-endian. */")?;
    writeln!(out, "#ifndef PBCARD_DPM_H")?;
    writeln!(out, "#define PBCARD_DPM_H")?;
    writeln!(out)?;
    writeln!(out, "/* ---- the image (docs/DPM.md) ---- */")?;
    let m = layout::MAGIC;
    writeln!(
        out,
        "#define PBCARD_{:<38} \"{}\"   /* HEADER.MAGIC */",
        "DPM_MAGIC",
        core::str::from_utf8(&m).unwrap_or("PBDM")
    )?;
    define(out, "DPM_LAYOUT_VERSION", format_args!("{}u", layout::LAYOUT_VERSION), "HEADER.LAYOUT_VERSION")?;
    define(out, "DPM_IMAGE_SIZE", format_args!("{}u", layout::IMAGE_SIZE), "bytes in the image")?;
    for (v, size) in layout::IMAGE_SIZE_OF_VERSION.iter().enumerate().skip(1) {
        let mut n = heapless::String::<32>::new();
        write!(n, "DPM_IMAGE_SIZE_V{v}")?;
        define(out, &n, format_args!("{size}u"), "image size of that layout version")?;
    }
    define(out, "PD_CAPACITY", format_args!("{}u", layout::PD_CAPACITY), "bytes of OUTPUTS / INPUTS DATA")?;
    define(out, "MBX_CAPACITY", format_args!("{}u", layout::MBX_CAPACITY), "bytes of mailbox VALUES")?;
    define(out, "EXT_DIAG_CAPACITY", format_args!("{}u", layout::EXT_DIAG_CAPACITY), "bytes of DRIVE.EXT_DIAG")?;
    define(out, "EXTRA_WORDS", format_args!("{}u", layout::EXTRA_WORDS), "DRIVE_CMD / DRIVE_STATE extra words")?;
    define(out, "CARD_EVENT_COUNT", format_args!("{}u", layout::CARD_EVENT_COUNT), "CARD.EVENTS counters")?;
    writeln!(out)?;
    writeln!(out, "/* HEADER.CAPABILITIES bits */")?;
    for (name, bit) in [
        ("CAP_IDENT", cap::IDENT),
        ("CAP_CARD_EVENTS", cap::CARD_EVENTS),
        ("CAP_DRIVE_REPORTS", cap::DRIVE_REPORTS),
        ("CAP_CONFIG", cap::CONFIG),
        ("CAP_MAILBOX", cap::MAILBOX),
        ("CAP_DRIVE_CMD", cap::DRIVE_CMD),
        ("CAP_DRIVE_STATE", cap::DRIVE_STATE),
        ("CAP_DEVICE", cap::DEVICE),
    ] {
        define(out, name, format_args!("0x{bit:02X}u"), "capability")?;
    }
    writeln!(out)?;
    writeln!(out, "/* DRIVE_CMD.OPERATE_MODE / CONFIG.OPERATE_MODE codes */")?;
    for (name, v) in [
        ("OPERATE_MODE_UNKNOWN", layout::operate_mode::UNKNOWN),
        ("OPERATE_MODE_PROFIDRIVE", layout::operate_mode::PROFIDRIVE),
        ("OPERATE_MODE_BYPASS", layout::operate_mode::BYPASS),
        ("OPERATE_MODE_ECHO", layout::operate_mode::ECHO),
    ] {
        define(out, name, format_args!("{v}u"), "operate mode")?;
    }
    for (i, b) in BLOCKS.iter().enumerate() {
        writeln!(out)?;
        let writer = match b.writer {
            Writer::Card => "card",
            Writer::Host => "host",
        };
        let seq = if b.sequenced { ", sequenced" } else { "" };
        writeln!(out, "/* {} (writer {writer}{seq}, since v{}): {} */", b.name, b.since, b.text)?;
        let mut n = heapless::String::<48>::new();
        ident(&mut n, b.name)?;
        let base = n.clone();
        n.push_str("_START").map_err(|_| fmt::Error)?;
        define(out, &n, format_args!("0x{:03X}u", b.start), "block start")?;
        let mut n = base.clone();
        n.push_str("_SIZE").map_err(|_| fmt::Error)?;
        define(out, &n, format_args!("{}u", b.len), "block length")?;
        let mut n = base.clone();
        n.push_str("_EVENT_BIT").map_err(|_| fmt::Error)?;
        define(out, &n, format_args!("{i}u"), "its bit in the pending-events bitmap")?;
        for f in FIELDS.iter().filter(|f| f.offset >= b.start && f.offset < b.start + b.len) {
            if f.ty == "reserved" {
                continue;
            }
            let mut n = heapless::String::<48>::new();
            ident(&mut n, f.name)?;
            define(out, &n, format_args!("0x{:02X}u", f.offset - b.start), f.ty)?;
            let mut a = n.clone();
            a.push_str("_ADDR").map_err(|_| fmt::Error)?;
            define(out, &a, format_args!("0x{:03X}u", f.offset), "absolute")?;
            if f.size > 2 {
                let mut z = n.clone();
                z.push_str("_SIZE").map_err(|_| fmt::Error)?;
                define(out, &z, format_args!("{}u", f.size), "bytes")?;
            }
        }
    }
    writeln!(out)?;
    writeln!(out, "/* ---- the SPI frames (docs/SPI.md) ---- */")?;
    define(out, "SPI_PROTOCOL_VERSION", format_args!("{}u", spi::PROTOCOL_VERSION), "STATUS data byte 0")?;
    for (name, c) in [
        ("SPI_CMD_READ", Command::Read),
        ("SPI_CMD_WRITE", Command::Write),
        ("SPI_CMD_STATUS", Command::Status),
        ("SPI_CMD_CYCLIC", Command::Cyclic),
    ] {
        define(out, name, format_args!("0x{:02X}u", c as u8), "request CMD")?;
    }
    for r in ResultCode::ALL {
        let name = match r {
            ResultCode::Ok => "SPI_RESULT_OK",
            ResultCode::CrcError => "SPI_RESULT_CRC_ERROR",
            ResultCode::BadCommand => "SPI_RESULT_BAD_COMMAND",
            ResultCode::BadLength => "SPI_RESULT_BAD_LENGTH",
            ResultCode::BadAddress => "SPI_RESULT_BAD_ADDRESS",
            ResultCode::ForbiddenWrite => "SPI_RESULT_FORBIDDEN_WRITE",
        };
        let line = if r.line_error() { "reply RESULT (line error: repeat)" } else { "reply RESULT" };
        define(out, name, format_args!("0x{:02X}u", r as u8), line)?;
    }
    for (name, v, doc) in [
        ("SPI_NO_REPLY", spi::NO_REPLY as usize, "reply byte 0: no reply in this transaction"),
        ("SPI_FLAG_EVENTS", spi::FLAG_EVENTS as usize, "reply FLAGS: events pending (IRQ)"),
        ("SPI_REQUEST_HEADER", spi::REQUEST_HEADER, "CMD TAG ADDR LEN"),
        ("SPI_REPLY_HEADER", spi::REPLY_HEADER, "RESULT TAG CMD FLAGS ADDR LEN"),
        ("SPI_CRC_LEN", spi::CRC_LEN, "CRC-16/CCITT-FALSE, high byte first"),
        ("SPI_MAX_DATA", spi::MAX_DATA, "most DATA bytes of a READ / WRITE"),
        ("SPI_MAX_REQUEST", spi::MAX_REQUEST, "longest request frame"),
        ("SPI_MAX_REPLY", spi::MAX_REPLY, "longest reply frame"),
        ("SPI_MAX_TRANSACTION", spi::MAX_TRANSACTION, "longest transaction"),
        ("SPI_STATUS_LEN", spi::STATUS_LEN, "bytes of STATUS data"),
        ("SPI_WRITE_ECHO_LEN", spi::WRITE_ECHO_LEN, "WRITE reply DATA: the request's CRC"),
        ("SPI_T_READY_US", spi::T_READY_US as usize, "gap between two transactions"),
        ("SPI_STATUS_VERSION", spi::status_data::VERSION, "STATUS data: protocol version"),
        ("SPI_STATUS_MAX_DATA", spi::status_data::MAX_DATA, "STATUS data: u16 MAX_DATA"),
        ("SPI_STATUS_IMAGE_SIZE", spi::status_data::IMAGE_SIZE, "STATUS data: u16 image size"),
        ("SPI_STATUS_EVENTS", spi::status_data::EVENTS, "STATUS data: u16 pending events"),
        ("SPI_STATUS_COUNTERS", spi::status_data::COUNTERS, "STATUS data: u16 x 6 counters"),
    ] {
        define(out, name, format_args!("{v}u"), doc)?;
    }
    define(out, "SPI_CRC_POLY", "0x1021u", "CRC-16/CCITT-FALSE polynomial")?;
    define(out, "SPI_CRC_INIT", "0xFFFFu", "initial value, no reflection, no final XOR")?;
    define(out, "SPI_CRC_CHECK", format_args!("0x{:04X}u", spi::crc16(b"123456789")), "crc of \"123456789\"")?;
    writeln!(out)?;
    writeln!(out, "/* CYCLIC request DATA (docs/SPI.md, \"The CYCLIC exchange\") */")?;
    for (name, v) in [
        ("CYC_REQ_HEARTBEAT", cyclic::req::HEARTBEAT),
        ("CYC_REQ_DRIVE_SEQ", cyclic::req::DRIVE_SEQ),
        ("CYC_REQ_STATE_SEQ", cyclic::req::STATE_SEQ),
        ("CYC_REQ_STATE_LEN", cyclic::req::STATE_LEN),
        ("CYC_REQ_RSP_OFF", cyclic::req::RSP_OFF),
        ("CYC_REQ_RSP_LEN", cyclic::req::RSP_LEN),
        ("CYC_REQ_REQ_OFF", cyclic::req::REQ_OFF),
        ("CYC_REQ_REQ_LEN", cyclic::req::REQ_LEN),
        ("CYC_REQ_STATE", cyclic::req::STATE),
    ] {
        define(out, name, format_args!("{v}u"), "offset in the request DATA")?;
    }
    writeln!(out, "/* CYCLIC reply DATA */")?;
    for (name, v) in [
        ("CYC_REP_EVENTS", cyclic::rep::EVENTS),
        ("CYC_REP_CARD_HEARTBEAT", cyclic::rep::CARD_HEARTBEAT),
        ("CYC_REP_CARD_FLAGS", cyclic::rep::CARD_FLAGS),
        ("CYC_REP_COMM_STATE", cyclic::rep::COMM_STATE),
        ("CYC_REP_BOOT_ID", cyclic::rep::BOOT_ID),
        ("CYC_REP_CARD_EVENTS", cyclic::rep::CARD_EVENTS),
        ("CYC_REP_CMD_SEQ", cyclic::rep::CMD_SEQ),
        ("CYC_REP_CMD_LEN", cyclic::rep::CMD_LEN),
        ("CYC_REP_REQ_LEN", cyclic::rep::REQ_LEN),
        ("CYC_REP_CMD", cyclic::rep::CMD),
    ] {
        define(out, name, format_args!("{v}u"), "offset in the reply DATA")?;
    }
    for (name, v, doc) in [
        ("CYC_REQUEST_FIXED", cyclic::REQUEST_FIXED, "request DATA before STATE"),
        ("CYC_REPLY_FIXED", cyclic::REPLY_FIXED, "reply DATA before CMD"),
        ("CYC_STATE_PAYLOAD", cyclic::STATE_PAYLOAD, "DRIVE_STATE bytes from FLAGS to the tail"),
        ("CYC_STATE_BASE", cyclic::STATE_BASE, "DRIVE_STATE bytes FLAGS..NAMUR"),
        ("CYC_CMD_BASE", cyclic::CMD_BASE, "DRIVE_CMD bytes FLAGS..EXTRA"),
        ("CYC_MAX_FRAGMENT", cyclic::MAX_FRAGMENT, "most bytes of a mailbox fragment"),
        ("CYC_MIN_FRAGMENT", cyclic::MIN_FRAGMENT, "fewest bytes of a mailbox fragment the reference hosts use"),
        (
            "CYC_TRANSACTION_BYTES",
            crate::dpm::host::Options::DEFAULT.cyclic_bytes,
            "the reference hosts' CYCLIC transaction budget (the mailbox fragments get what the telegram leaves)",
        ),
        ("CYC_MAX_REQUEST_DATA", cyclic::MAX_REQUEST_DATA, "longest CYCLIC request DATA"),
        ("CYC_MAX_REPLY_DATA", cyclic::MAX_REPLY_DATA, "longest CYCLIC reply DATA"),
    ] {
        define(out, name, format_args!("{v}u"), doc)?;
    }
    writeln!(out)?;
    writeln!(out, "#endif /* PBCARD_DPM_H */")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn c_header_is_current() {
        let mut h = String::new();
        write_c_header(&mut h).unwrap();
        // Every name is defined once.
        let mut names: Vec<&str> = h.lines().filter_map(|l| l.strip_prefix("#define ")?.split(' ').next()).collect();
        names.sort_unstable();
        let twice: Vec<&str> = names.windows(2).filter(|w| w[0] == w[1]).map(|w| w[0]).collect();
        assert!(twice.is_empty(), "defined twice: {twice:?}");
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../c-host/include/pbcard_dpm.h");
        if std::env::var_os("DPM_DOC_WRITE").is_some() {
            std::fs::create_dir_all(concat!(env!("CARGO_MANIFEST_DIR"), "/../../c-host/include")).unwrap();
            std::fs::write(path, &h).unwrap();
        }
        let committed = std::fs::read_to_string(path).unwrap_or_default();
        assert!(
            committed == h,
            "c-host/include/pbcard_dpm.h differs from crates/dpm/src/dpm/layout.rs / spi.rs; regenerate it with\n  \
             DPM_DOC_WRITE=1 cargo test -p pbcard-dpm --lib --target x86_64-unknown-linux-gnu dpm::c_header"
        );
    }
}
