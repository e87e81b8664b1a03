//! The block codecs on raw bytes, for a host that reaches the image through a transport
//! (the host reference implementation `dpm-host/`, an SPI client) instead of a [`Dpm`]
//! value: one typed handle per block of [`layout::BLOCKS`] with its place in the map and the
//! sequenced-block rules of [`super`] (the same encoders and decoders [`CardSide`] and
//! [`HostSide`] use, so the layout exists once).
//!
//! [`BlockCodec::decode`] takes the block's bytes as read in one ascending pass and gives the
//! content only when `SEQ_HEAD` = `SEQ_TAIL`; [`BlockCodec::encode`] builds the bytes of one
//! complete write with a given sequence counter, for a transport that writes them in one
//! ascending pass (the host's order). Wrong lengths are refused, never a panic.
//!
//! [`Dpm`]: super::Dpm
//! [`CardSide`]: super::CardSide
//! [`HostSide`]: super::HostSide

use super::layout::{self, Writer};
use super::{
    get16, put16, CardReport, DriveCommandImage, DriveReport, DriveStateImage, HostConfig, Identity, MailboxRequest,
    MailboxResponse, ProcessData, Status, Torn,
};
use crate::dpv1::im::DeviceIdent;

/// Why [`BlockCodec::decode`] / [`BlockCodec::encode`] gave nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum BlockError {
    /// The byte slice is not the block's length.
    Length {
        /// The block's length.
        expected: usize,
        /// The slice's length.
        got: usize,
    },
    /// The two sequence counters differ: a write was in progress. Read again.
    Torn(Torn),
}

impl From<Torn> for BlockError {
    fn from(t: Torn) -> Self {
        BlockError::Torn(t)
    }
}

/// One block of the map with its content type `T`.
#[derive(Debug)]
pub struct BlockCodec<T: 'static> {
    block: &'static layout::Block,
    decode: fn(&[u8]) -> T,
    encode: fn(&T, &mut [u8]),
}

impl<T> BlockCodec<T> {
    /// The block's entry in [`layout::BLOCKS`] (name, start, length, writer, version).
    pub const fn block(&self) -> &'static layout::Block {
        self.block
    }

    /// Absolute offset of the block.
    pub const fn start(&self) -> usize {
        self.block.start
    }

    /// Length of the block in bytes.
    pub const fn len(&self) -> usize {
        self.block.len
    }

    /// Never empty (clippy's companion of [`Self::len`]).
    pub const fn is_empty(&self) -> bool {
        self.block.len == 0
    }

    /// Who writes the block.
    pub const fn writer(&self) -> Writer {
        self.block.writer
    }

    /// The sequence counters of `bytes` (a block read), `(head, tail)`; `None` for a wrong
    /// length or an unsequenced block.
    pub fn counters(&self, bytes: &[u8]) -> Option<(u16, u16)> {
        (self.block.sequenced && bytes.len() == self.block.len)
            .then(|| (get16(bytes, 0), get16(bytes, bytes.len() - 2)))
    }

    /// The content of one read of the whole block, with its sequence counter (0 for an
    /// unsequenced block or a block never written).
    pub fn decode(&self, bytes: &[u8]) -> Result<(u16, T), BlockError> {
        self.check_len(bytes.len())?;
        let seq = if self.block.sequenced {
            let (head, tail) = (get16(bytes, 0), get16(bytes, bytes.len() - 2));
            if head != tail {
                return Err(Torn { head, tail }.into());
            }
            head
        } else {
            0
        };
        Ok((seq, (self.decode)(bytes)))
    }

    /// The bytes of a complete write of `value` with sequence counter `seq` (both counters;
    /// ignored for an unsequenced block) into `out` (the block's length). Reserved bytes are 0.
    pub fn encode(&self, value: &T, seq: u16, out: &mut [u8]) -> Result<(), BlockError> {
        self.check_len(out.len())?;
        out.fill(0);
        (self.encode)(value, out);
        if self.block.sequenced {
            put16(out, 0, seq);
            put16(out, self.block.len - 2, seq);
        }
        Ok(())
    }

    fn check_len(&self, got: usize) -> Result<(), BlockError> {
        if got == self.block.len {
            Ok(())
        } else {
            Err(BlockError::Length { expected: self.block.len, got })
        }
    }
}

/// The header block's content.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// `HEADER.MAGIC` ([`layout::MAGIC`] for a valid image).
    pub magic: [u8; 4],
    /// `HEADER.LAYOUT_VERSION`.
    pub layout_version: u16,
    /// `HEADER.IMAGE_SIZE`.
    pub image_size: u16,
    /// `HEADER.CAPABILITIES` ([`layout::cap`]; 0 for layout version 1).
    pub capabilities: u32,
}

impl Header {
    /// The header this crate's [`Dpm::new`](super::Dpm::new) writes.
    pub const THIS_LAYOUT: Header = Header {
        magic: layout::MAGIC,
        layout_version: layout::LAYOUT_VERSION,
        image_size: layout::IMAGE_SIZE as u16,
        capabilities: layout::cap::ALL,
    };

    fn encode(&self, b: &mut [u8]) {
        b[layout::header::MAGIC..layout::header::MAGIC + 4].copy_from_slice(&self.magic);
        put16(b, layout::header::LAYOUT_VERSION, self.layout_version);
        put16(b, layout::header::IMAGE_SIZE, self.image_size);
        b[layout::header::CAPABILITIES..layout::header::CAPABILITIES + 4]
            .copy_from_slice(&self.capabilities.to_be_bytes());
    }

    fn decode(b: &[u8]) -> Header {
        let c = layout::header::CAPABILITIES;
        let mut magic = [0u8; 4];
        magic.copy_from_slice(&b[layout::header::MAGIC..layout::header::MAGIC + 4]);
        Header {
            magic,
            layout_version: get16(b, layout::header::LAYOUT_VERSION),
            image_size: get16(b, layout::header::IMAGE_SIZE),
            capabilities: if get16(b, layout::header::LAYOUT_VERSION) >= 2 {
                u32::from_be_bytes([b[c], b[c + 1], b[c + 2], b[c + 3]])
            } else {
                0
            },
        }
    }
}

const fn block(i: usize) -> &'static layout::Block {
    &layout::BLOCKS[i]
}

/// HEADER (not sequenced).
pub const HEADER: BlockCodec<Header> = BlockCodec { block: block(0), decode: Header::decode, encode: Header::encode };
/// STATUS.
pub const STATUS: BlockCodec<Status> = BlockCodec { block: block(1), decode: Status::decode, encode: Status::encode };
/// OUTPUTS (`seq` of the decoded value is the block's counter).
pub const OUTPUTS: BlockCodec<ProcessData> =
    BlockCodec { block: block(2), decode: ProcessData::decode, encode: ProcessData::encode };
/// INPUTS (the value's own `seq` is ignored when encoding: the `seq` argument counts).
pub const INPUTS: BlockCodec<ProcessData> =
    BlockCodec { block: block(3), decode: ProcessData::decode, encode: ProcessData::encode };
/// IDENT (not sequenced).
pub const IDENT: BlockCodec<Identity> =
    BlockCodec { block: block(4), decode: Identity::decode, encode: Identity::encode };
/// CARD.
pub const CARD: BlockCodec<CardReport> =
    BlockCodec { block: block(5), decode: CardReport::decode, encode: CardReport::encode };
/// DRIVE.
pub const DRIVE: BlockCodec<DriveReport> =
    BlockCodec { block: block(6), decode: DriveReport::decode, encode: DriveReport::encode };
/// CONFIG.
pub const CONFIG: BlockCodec<HostConfig> =
    BlockCodec { block: block(7), decode: HostConfig::decode, encode: HostConfig::encode };
/// MBX_REQ (`None`: no request written yet, or an unknown kind).
pub const MBX_REQ: BlockCodec<Option<MailboxRequest>> =
    BlockCodec { block: block(8), decode: MailboxRequest::decode, encode: encode_request };
/// MBX_RSP.
pub const MBX_RSP: BlockCodec<MailboxResponse> =
    BlockCodec { block: block(9), decode: MailboxResponse::decode, encode: MailboxResponse::encode };
/// DRIVE_CMD (layout version 3).
pub const DRIVE_CMD: BlockCodec<DriveCommandImage> =
    BlockCodec { block: block(10), decode: DriveCommandImage::decode, encode: DriveCommandImage::encode };
/// DRIVE_STATE (layout version 3).
pub const DRIVE_STATE: BlockCodec<DriveStateImage> =
    BlockCodec { block: block(11), decode: DriveStateImage::decode, encode: DriveStateImage::encode };

/// DEVICE (layout version 4): the drive's serial number and hardware revision for I&M0.
pub const DEVICE: BlockCodec<DeviceIdent> =
    BlockCodec { block: block(12), decode: decode_device, encode: encode_device };

/// The DEVICE block's decoder (for the card-side reader).
pub(super) const DEVICE_DECODE: fn(&[u8]) -> DeviceIdent = decode_device;
/// The DEVICE block's encoder (for the host-side writer).
pub(super) const DEVICE_ENCODE: fn(&DeviceIdent, &mut [u8]) = encode_device;

fn decode_device(b: &[u8]) -> DeviceIdent {
    let mut serial_number = [0u8; 16];
    let s = layout::device::SERIAL_NUMBER;
    serial_number.copy_from_slice(&b[s..s + 16]);
    DeviceIdent { serial_number, hardware_revision: get16(b, layout::device::HARDWARE_REVISION) }
}

fn encode_device(d: &DeviceIdent, b: &mut [u8]) {
    let s = layout::device::SERIAL_NUMBER;
    b[s..s + 16].copy_from_slice(&d.serial_number);
    put16(b, layout::device::HARDWARE_REVISION, d.hardware_revision);
}

fn encode_request(r: &Option<MailboxRequest>, b: &mut [u8]) {
    if let Some(r) = r {
        r.encode(b);
    }
}

const _: () = {
    assert!(layout::BLOCKS.len() == 13);
    assert!(DEVICE.block.start == layout::device::START);
    assert!(HEADER.block.start == layout::header::START && STATUS.block.start == layout::status::START);
    assert!(OUTPUTS.block.start == layout::outputs::START && INPUTS.block.start == layout::inputs::START);
    assert!(IDENT.block.start == layout::ident::START && CARD.block.start == layout::card::START);
    assert!(DRIVE.block.start == layout::drive::START && CONFIG.block.start == layout::config::START);
    assert!(MBX_REQ.block.start == layout::mbx_req::START && MBX_RSP.block.start == layout::mbx_rsp::START);
    assert!(DRIVE_CMD.block.start == layout::drive_cmd::START);
    assert!(DRIVE_STATE.block.start == layout::drive_state::START);
};

#[cfg(test)]
mod tests {
    //! Property tests: every block decoder on arbitrary bytes of any length never panics,
    //! refuses a wrong length and a torn block with the right error, and what it decodes
    //! encodes back to bytes that decode to the same value and counter (the host and the card
    //! agree on every value either side can read).
    use super::*;
    use core::fmt::Debug;
    use proptest::prelude::*;
    use proptest::test_runner::TestCaseError;

    fn check<T: PartialEq + Debug>(c: &BlockCodec<T>, bytes: &[u8]) -> Result<(), TestCaseError> {
        match c.decode(bytes) {
            Err(BlockError::Length { expected, got }) => {
                prop_assert_eq!((expected, got), (c.len(), bytes.len()));
                prop_assert_ne!(got, expected);
                prop_assert_eq!(c.counters(bytes), None);
            }
            Err(BlockError::Torn(t)) => {
                prop_assert!(c.block().sequenced);
                prop_assert_ne!(t.head, t.tail);
                prop_assert_eq!(c.counters(bytes), Some((t.head, t.tail)));
            }
            Ok((seq, v)) => {
                prop_assert_eq!(bytes.len(), c.len());
                if c.block().sequenced {
                    prop_assert_eq!(c.counters(bytes), Some((seq, seq)));
                } else {
                    prop_assert_eq!(seq, 0);
                }
                let mut out = [0u8; 256];
                let out = &mut out[..c.len()];
                prop_assert!(c.encode(&v, seq, out).is_ok());
                let (seq2, v2) = c.decode(out).map_err(|e| TestCaseError::fail(format!("{e:?}")))?;
                prop_assert_eq!(seq2, seq);
                prop_assert_eq!(&v2, &v, "decode(encode(v)) ≠ v for {}", c.block().name);
                let mut again = [0u8; 256];
                prop_assert!(c.encode(&v2, seq2, &mut again[..c.len()]).is_ok());
                prop_assert_eq!(&again[..c.len()], &*out, "encoding is not canonical for {}", c.block().name);
            }
        }
        // Encoding into a wrong-sized buffer is refused, never a panic.
        let mut short = [0u8; 3];
        if c.len() != short.len() {
            if let Ok((seq, v)) = c.decode(bytes) {
                let refused = matches!(c.encode(&v, seq, &mut short), Err(BlockError::Length { .. }));
                prop_assert!(refused);
            }
        }
        Ok(())
    }

    /// Block `i` of the map on `bytes`.
    fn check_block(i: usize, bytes: &[u8]) -> Result<(), TestCaseError> {
        match i {
            0 => check(&HEADER, bytes),
            1 => check(&STATUS, bytes),
            2 => check(&OUTPUTS, bytes),
            3 => check(&INPUTS, bytes),
            4 => check(&IDENT, bytes),
            5 => check(&CARD, bytes),
            6 => check(&DRIVE, bytes),
            7 => check(&CONFIG, bytes),
            8 => check(&MBX_REQ, bytes),
            9 => check(&MBX_RSP, bytes),
            10 => check(&DRIVE_CMD, bytes),
            11 => check(&DRIVE_STATE, bytes),
            _ => check(&DEVICE, bytes),
        }
    }

    #[test]
    fn every_block_fits_the_test_buffers() {
        assert!(layout::BLOCKS.iter().all(|b| b.len <= 256 && b.len != 3));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2048))]

        /// Arbitrary bytes: any length, the block's length, and the block's length with equal
        /// counters (so the content decoders are reached).
        #[test]
        fn decode_never_panics_and_round_trips(
            i in 0usize..13,
            mut raw in proptest::collection::vec(any::<u8>(), 0..300),
            mode in 0u8..3,
            seq in any::<u16>(),
        ) {
            let b = &layout::BLOCKS[i];
            if mode > 0 {
                raw.resize(b.len, 0);
            }
            if mode == 2 && b.sequenced {
                put16(&mut raw, 0, seq);
                put16(&mut raw, b.len - 2, seq);
            }
            check_block(i, &raw)?;
        }
    }
}
