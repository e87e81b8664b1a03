//! FDL frame formats (IEC 61158-4-3; reference §2.1–2.3).
//!
//! | frame | bytes | checksum covers |
//! |---|---|---|
//! | SD1 `10 DA SA FC FCS 16` | 6 | DA SA FC |
//! | SD2 `68 LE LEr 68 DA SA FC [DAE][SAE] DU FCS 16` | LE + 6 | DA … last DU byte |
//! | SD3 `A2 DA SA FC DU[8] FCS 16` | 14 | DA … DU |
//! | SD4 `DC DA SA` (token) | 3 | — |
//! | SC `E5` (short acknowledge) | 1 | — |
//!
//! [`decode`] checks untrusted bytes and gives one of three outcomes: more bytes are needed
//! ([`Decoded::Incomplete`]), a frame of `n` bytes ([`Decoded::Frame`]), or why the bytes are
//! not a frame ([`Decoded::Invalid`]). [`Header`] + [`emit`] build responses.

/// Start delimiter of SD1 (no data unit).
pub const SD1: u8 = 0x10;
/// Start delimiter of SD2 (variable data unit).
pub const SD2: u8 = 0x68;
/// Start delimiter of SD3 (fixed 8-byte data unit).
pub const SD3: u8 = 0xA2;
/// Start delimiter of SD4 (token).
pub const SD4: u8 = 0xDC;
/// The short acknowledge SC.
pub const SC: u8 = 0xE5;
/// End delimiter.
pub const ED: u8 = 0x16;
/// The broadcast / multicast station address (reference §2.2).
pub const BROADCAST: u8 = 127;
/// The highest address a station may have (0..=126; 127 is [`BROADCAST`], reference §2.2).
pub const MAX_STATION_ADDRESS: u8 = 126;
/// Largest SD2 LE (reference §2.1).
pub const LE_MAX: u8 = 249;
/// Smallest SD2 LE.
pub const LE_MIN: u8 = 4;
/// Longest telegram on the wire (SD2 with LE = 249).
pub const MAX_FRAME_LEN: usize = LE_MAX as usize + 6;
/// Largest data unit of an SD2 frame including extension bytes (LE − DA, SA, FC).
pub const MAX_DU_LEN: usize = LE_MAX as usize - 3;

/// Why bytes are not a valid telegram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrameError {
    /// The first byte is no start delimiter (SD1/SD2/SD3/SD4/SC).
    UnknownStartDelimiter(u8),
    /// SD2: LE ≠ LEr.
    LengthMismatch {
        /// LE
        le: u8,
        /// LEr
        ler: u8,
    },
    /// SD2: LE outside 4..=249.
    LengthOutOfRange(u8),
    /// SD2: the fourth byte does not repeat the start delimiter.
    RepeatedSdMismatch(u8),
    /// The frame checksum does not match.
    Checksum {
        /// the FCS byte received
        received: u8,
        /// the sum computed over the covered bytes
        computed: u8,
    },
    /// The end delimiter is not 0x16.
    EndDelimiter(u8),
    /// The DA/SA extension bit announces an address-extension byte but the DU has none.
    MissingExtension,
    /// An extension byte selects a region/segment address (b6 = 1), which a DP slave on one
    /// segment does not support.
    RegionAddress,
    /// More than one DAE or SAE byte (b7 = 1 on an extension byte): chained extensions only
    /// carry region/segment addresses.
    ChainedExtension,
}

/// FDL function code byte (reference §2.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct FunctionCode(pub u8);

/// The function of a request frame (FC bits 3..0 with b6 = 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum RequestFunction {
    /// 0: time event / clock value (DP-V2).
    TimeEvent,
    /// 3: Send Data with Acknowledge, low priority.
    SdaLow,
    /// 4: Send Data with No acknowledge, low priority.
    SdnLow,
    /// 5: SDA high.
    SdaHigh,
    /// 6: SDN high.
    SdnHigh,
    /// 7: Send and Request Data with multicast reply.
    Msrd,
    /// 9: Request FDL status.
    FdlStatus,
    /// 0xC: Send and Request Data, low priority.
    SrdLow,
    /// 0xD: SRD high.
    SrdHigh,
    /// 0xE: request ident (with reply).
    Ident,
    /// 0xF: request LSAP status.
    LsapStatus,
    /// Any other code (1, 2, 8, 0xA, 0xB: reserved / TE / CE).
    Other(u8),
}

/// The status of a response frame (FC bits 3..0 with b6 = 0; reference §2.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ResponseStatus {
    /// 0: OK (also the FDL_Status answer of a slave).
    Ok = 0x0,
    /// 1: user error.
    Ue = 0x1,
    /// 2: no resources.
    Rr = 0x2,
    /// 3: no service activated (SAP not enabled).
    Rs = 0x3,
    /// 8: response data, low priority.
    Dl = 0x8,
    /// 9: no response data.
    Nr = 0x9,
    /// 0xA: response data, high priority (DP: new diagnosis).
    Dh = 0xA,
    /// 0xC: data not received, response data low.
    Rdl = 0xC,
    /// 0xD: data not received, response data high.
    Rdh = 0xD,
}

impl FunctionCode {
    /// The FC of a slave's response (station type bits 5..4 = 00 "slave").
    pub const fn response(status: ResponseStatus) -> Self {
        FunctionCode(status as u8)
    }
    /// A request FC (b6 = 1) with the given function bits and frame count bits.
    pub const fn request(function: u8, fcb: bool, fcv: bool) -> Self {
        FunctionCode(0x40 | ((fcb as u8) << 5) | ((fcv as u8) << 4) | (function & 0x0F))
    }
    /// b6: request (send/request frame) rather than response.
    pub const fn is_request(self) -> bool {
        self.0 & 0x40 != 0
    }
    /// b5 of a request: frame count bit.
    pub const fn fcb(self) -> bool {
        self.0 & 0x20 != 0
    }
    /// b4 of a request: frame count bit valid.
    pub const fn fcv(self) -> bool {
        self.0 & 0x10 != 0
    }
    /// The request function (meaningful when [`is_request`](Self::is_request)).
    pub const fn function(self) -> RequestFunction {
        match self.0 & 0x0F {
            0x0 => RequestFunction::TimeEvent,
            0x3 => RequestFunction::SdaLow,
            0x4 => RequestFunction::SdnLow,
            0x5 => RequestFunction::SdaHigh,
            0x6 => RequestFunction::SdnHigh,
            0x7 => RequestFunction::Msrd,
            0x9 => RequestFunction::FdlStatus,
            0xC => RequestFunction::SrdLow,
            0xD => RequestFunction::SrdHigh,
            0xE => RequestFunction::Ident,
            0xF => RequestFunction::LsapStatus,
            x => RequestFunction::Other(x),
        }
    }
}

/// Which data frame format carried a telegram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum DataFormat {
    /// SD1, no data unit.
    Sd1,
    /// SD2, variable data unit.
    Sd2,
    /// SD3, eight-byte data unit.
    Sd3,
}

/// A decoded data telegram (SD1/SD2/SD3): a view into the received bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DataTelegram<'a> {
    /// Frame format.
    pub format: DataFormat,
    /// Destination address (0..=127, extension bit removed).
    pub da: u8,
    /// Source address (0..=127, extension bit removed).
    pub sa: u8,
    /// Function code.
    pub fc: FunctionCode,
    /// Destination SAP from the DAE byte, `None` = default SAP (Data_Exchange).
    pub dsap: Option<u8>,
    /// Source SAP from the SAE byte.
    pub ssap: Option<u8>,
    /// The data unit after the extension bytes.
    pub pdu: &'a [u8],
}

/// Any telegram a station may see on the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Telegram<'a> {
    /// SD1/SD2/SD3.
    Data(DataTelegram<'a>),
    /// SD4 token frame (parsed, ignored by a slave).
    Token {
        /// destination (next token holder)
        da: u8,
        /// source
        sa: u8,
    },
    /// SC short acknowledge.
    ShortAck,
}

/// The three outcomes of decoding untrusted bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decoded<'a> {
    /// The bytes are a valid prefix; more are needed.
    Incomplete,
    /// A telegram occupying the first `len` bytes.
    Frame(Telegram<'a>, usize),
    /// Not a telegram.
    Invalid(FrameError),
}

/// The FCS: arithmetic sum modulo 256 (reference §2.1).
///
/// Summed a word at a time (SWAR, on the response path for every received and sent frame):
/// each 32-bit word adds its bytes 0 and 2 and its bytes 1 and 3 into two 16-bit lanes, which
/// hold at least 128 words (128 × 2 × 255 < 2¹⁶) before they are folded; the byte sum modulo
/// 256 is the sum of the lanes' low bytes. Equal to the byte-by-byte sum for every input
/// (`fcs_word_sum_equals_byte_sum`).
#[inline]
pub fn fcs(bytes: &[u8]) -> u8 {
    const LANES: u32 = 0x00FF_00FF;
    const BLOCK: usize = 4 * 128;
    if bytes.len() < 16 {
        // A header (SD1: three bytes): no word setup.
        return bytes.iter().fold(0u8, |acc, b| acc.wrapping_add(*b));
    }
    if bytes.len() > BLOCK {
        let (a, b) = bytes.split_at(BLOCK);
        return fcs(a).wrapping_add(fcs(b));
    }
    let mut words = bytes.chunks_exact(4);
    let mut lanes = 0u32;
    for c in &mut words {
        let w = u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
        lanes += (w & LANES) + ((w >> 8) & LANES);
    }
    let sum = words.remainder().iter().fold(lanes.wrapping_add(lanes >> 16) as u8, |acc, b| acc.wrapping_add(*b));
    sum
}

/// The total frame length announced by the first bytes of `buf`: `Ok(None)` while too few
/// bytes are in to know (SD2 needs four: SD LE LEr SD), an error if the header is invalid.
/// This is what a DMA receiver uses to size the transfer as soon as the header is in.
pub fn frame_len(buf: &[u8]) -> Result<Option<usize>, FrameError> {
    let Some(&sd) = buf.first() else { return Ok(None) };
    match sd {
        SD1 => Ok(Some(6)),
        SD3 => Ok(Some(14)),
        SD4 => Ok(Some(3)),
        SC => Ok(Some(1)),
        SD2 => {
            if let Some(&le) = buf.get(1) {
                if !(LE_MIN..=LE_MAX).contains(&le) {
                    return Err(FrameError::LengthOutOfRange(le));
                }
                if let Some(&ler) = buf.get(2) {
                    if ler != le {
                        return Err(FrameError::LengthMismatch { le, ler });
                    }
                }
                if let Some(&sd) = buf.get(3) {
                    if sd != SD2 {
                        return Err(FrameError::RepeatedSdMismatch(sd));
                    }
                    return Ok(Some(le as usize + 6));
                }
            }
            Ok(None)
        }
        other => Err(FrameError::UnknownStartDelimiter(other)),
    }
}

/// Decode the telegram at the start of `buf` (trailing bytes are left alone).
pub fn decode(buf: &[u8]) -> Decoded<'_> {
    decode_with(buf, None)
}

/// [`decode`] for a receiver that summed the checksum while the bytes arrived (issue 11,
/// `phy::stream`): `sum` is [`fcs`] of the bytes the FCS covers (DA … last DU byte, see the
/// module table), and the outcome is `decode(buf)`'s when it is — in constant time, with no
/// pass over the data unit (the delimiters, lengths, FCS byte, ED and the extension bytes are
/// checked as [`decode`] checks them).
pub fn decode_summed(buf: &[u8], sum: u8) -> Decoded<'_> {
    decode_with(buf, Some(sum))
}

/// Where the bytes the FCS covers start in a data frame that starts with `sd` (SD2: after
/// `SD LE LEr SD`; SD1 / SD3: after SD).
pub const fn covered_start(sd: u8) -> usize {
    if sd == SD2 {
        4
    } else {
        1
    }
}

fn decode_with(buf: &[u8], sum: Option<u8>) -> Decoded<'_> {
    let len = match frame_len(buf) {
        Ok(Some(len)) => len,
        Ok(None) => return Decoded::Incomplete,
        Err(e) => return Decoded::Invalid(e),
    };
    if buf.len() < len {
        return Decoded::Incomplete;
    }
    let frame = &buf[..len];
    match frame[0] {
        SC => Decoded::Frame(Telegram::ShortAck, 1),
        SD4 => Decoded::Frame(Telegram::Token { da: frame[1] & 0x7F, sa: frame[2] & 0x7F }, 3),
        sd => {
            let (format, body) = match sd {
                SD1 => (DataFormat::Sd1, &frame[1..4]),
                SD3 => (DataFormat::Sd3, &frame[1..12]),
                _ => (DataFormat::Sd2, &frame[4..len - 2]),
            };
            let received = frame[len - 2];
            let computed = match sum {
                Some(s) => s,
                None => fcs(body),
            };
            if received != computed {
                return Decoded::Invalid(FrameError::Checksum { received, computed });
            }
            if frame[len - 1] != ED {
                return Decoded::Invalid(FrameError::EndDelimiter(frame[len - 1]));
            }
            match split_body(format, body) {
                Ok(t) => Decoded::Frame(Telegram::Data(t), len),
                Err(e) => Decoded::Invalid(e),
            }
        }
    }
}

fn split_body(format: DataFormat, body: &[u8]) -> Result<DataTelegram<'_>, FrameError> {
    let (da_raw, sa_raw, fc) = (body[0], body[1], FunctionCode(body[2]));
    let mut du = &body[3..];
    let mut take_ext = |present: bool| -> Result<Option<u8>, FrameError> {
        if !present {
            return Ok(None);
        }
        let (&ext, rest) = du.split_first().ok_or(FrameError::MissingExtension)?;
        if ext & 0x40 != 0 {
            return Err(FrameError::RegionAddress);
        }
        if ext & 0x80 != 0 {
            return Err(FrameError::ChainedExtension);
        }
        du = rest;
        Ok(Some(ext & 0x3F))
    };
    let dsap = take_ext(da_raw & 0x80 != 0)?;
    let ssap = take_ext(sa_raw & 0x80 != 0)?;
    Ok(DataTelegram { format, da: da_raw & 0x7F, sa: sa_raw & 0x7F, fc, dsap, ssap, pdu: du })
}

/// The addressing part of a data telegram to be sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Header {
    /// Destination address.
    pub da: u8,
    /// Source address.
    pub sa: u8,
    /// Function code.
    pub fc: FunctionCode,
    /// Destination SAP (`None` = default SAP).
    pub dsap: Option<u8>,
    /// Source SAP.
    pub ssap: Option<u8>,
}

impl Header {
    /// The response header to a request: addresses and SAPs swapped (reference §2.2).
    pub fn response_to(req: &DataTelegram<'_>, status: ResponseStatus) -> Header {
        Header { da: req.sa, sa: req.da, fc: FunctionCode::response(status), dsap: req.ssap, ssap: req.dsap }
    }
    fn ext_len(&self) -> usize {
        self.dsap.is_some() as usize + self.ssap.is_some() as usize
    }
}

/// Bytes needed to emit a frame with `header` and a data unit of `pdu_len` bytes.
pub const fn encoded_len(ext_len: usize, pdu_len: usize) -> usize {
    match ext_len + pdu_len {
        0 => 6,
        8 => 14,
        du => du + 9,
    }
}

/// Why a frame could not be emitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum EmitError {
    /// Data unit longer than an SD2 frame can carry.
    TooLong,
    /// Output buffer too small.
    BufferTooSmall,
}

/// Emit a data telegram into `out`, choosing the format as profirust and the ASICs do: SD1 when
/// the data unit (extension bytes + PDU) is empty, SD3 when it is exactly 8 bytes, SD2
/// otherwise (reference §2.1). Returns the frame length.
pub fn emit(out: &mut [u8], header: &Header, pdu: &[u8]) -> Result<usize, EmitError> {
    let n = emit_header(out, header, pdu.len())?;
    let start = n - 2 - pdu.len();
    out[start..start + pdu.len()].copy_from_slice(pdu);
    finish(out, n);
    Ok(n)
}

/// Lay out the frame for `header` and a `pdu_len`-byte PDU, leaving the PDU bytes and the FCS
/// to the caller (see [`pdu_range`] and [`finish`]). Returns the frame length. This is how
/// pre-staged responses are built without an intermediate copy.
pub fn emit_header(out: &mut [u8], header: &Header, pdu_len: usize) -> Result<usize, EmitError> {
    let ext = header.ext_len();
    let du = ext + pdu_len;
    if du > MAX_DU_LEN {
        return Err(EmitError::TooLong);
    }
    let n = encoded_len(ext, pdu_len);
    if out.len() < n {
        return Err(EmitError::BufferTooSmall);
    }
    let mut i = match du {
        0 => {
            out[0] = SD1;
            1
        }
        8 => {
            out[0] = SD3;
            1
        }
        _ => {
            let le = (du + 3) as u8;
            out[..4].copy_from_slice(&[SD2, le, le, SD2]);
            4
        }
    };
    out[i] = header.da | if header.dsap.is_some() { 0x80 } else { 0 };
    out[i + 1] = header.sa | if header.ssap.is_some() { 0x80 } else { 0 };
    out[i + 2] = header.fc.0;
    i += 3;
    if let Some(d) = header.dsap {
        out[i] = d & 0x3F;
        i += 1;
    }
    if let Some(s) = header.ssap {
        out[i] = s & 0x3F;
    }
    out[n - 1] = ED;
    Ok(n)
}

/// Where the PDU of an `n`-byte frame laid out by [`emit_header`] with `pdu_len` PDU bytes lies.
pub const fn pdu_range(n: usize, pdu_len: usize) -> core::ops::Range<usize> {
    n - 2 - pdu_len..n - 2
}

/// Compute and store the FCS of the `n`-byte data frame in `out[..n]`.
pub fn finish(out: &mut [u8], n: usize) {
    let start = if out[0] == SD2 { 4 } else { 1 };
    out[n - 2] = fcs(&out[start..n - 2]);
}

/// Emit the short acknowledge SC. Returns 1.
pub fn emit_sc(out: &mut [u8]) -> usize {
    out[0] = SC;
    1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `decode_summed` with the right sum is `decode`, for valid frames and for every
    /// corruption of them; with a wrong sum it reports the checksum.
    #[test]
    fn decode_summed_equals_decode() {
        let hdr = Header { da: 8, sa: 2, fc: FunctionCode(0x7D), dsap: Some(60), ssap: Some(62) };
        for n in [0usize, 1, 5, 8, 40, 244] {
            let pdu: std::vec::Vec<u8> = (0..n as u8).collect();
            let mut out = [0u8; MAX_FRAME_LEN];
            let h = Header { dsap: if n == 1 { None } else { hdr.dsap }, ..hdr };
            let len = emit(&mut out, &h, &pdu).unwrap();
            for cut in [len, len - 1, len + 1] {
                for flip in [None, Some(0), Some(1), Some(3), Some(4), Some(len - 2), Some(len - 1)] {
                    let mut f = out;
                    if let Some(i) = flip {
                        f[i] ^= 0x41;
                    }
                    let f = &f[..cut.min(MAX_FRAME_LEN)];
                    let s = covered_start(f[0]);
                    let end = frame_len(f).ok().flatten().map_or(s, |l| l.saturating_sub(2)).clamp(s, f.len().max(s));
                    let sum = fcs(f.get(s..end).unwrap_or(&[]));
                    assert_eq!(decode_summed(f, sum), decode(f), "{n} {cut} {flip:?}");
                }
            }
            if let Decoded::Frame(..) = decode(&out[..len]) {
                let s = covered_start(out[0]);
                let sum = fcs(&out[s..len - 2]).wrapping_add(1);
                assert!(matches!(decode_summed(&out[..len], sum), Decoded::Invalid(FrameError::Checksum { .. })));
            }
        }
    }

    /// The word-wise FCS equals the byte-by-byte sum for every length and alignment.
    #[test]
    fn fcs_word_sum_equals_byte_sum() {
        let data: std::vec::Vec<u8> = (0..2100u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        let ones = [0xFFu8; 1500];
        for src in [&data[..], &ones[..]] {
            for start in 0..4 {
                for len in (0..300).chain([511, 512, 513, 1024, 1025, 1400]) {
                    let b = &src[start..start + len];
                    let want = b.iter().fold(0u8, |a, x| a.wrapping_add(*x));
                    assert_eq!(fcs(b), want, "start {start} len {len}");
                }
            }
        }
    }

    /// profirust's bring-up at 1.5 Mbit/s (reference toolchain.md): FDL_Status request.
    const FDL_STATUS_REQ: [u8; 6] = [0x10, 0x08, 0x02, 0x49, 0x53, 0x16];

    #[test]
    fn golden_sd1_fdl_status() {
        match decode(&FDL_STATUS_REQ) {
            Decoded::Frame(Telegram::Data(t), 6) => {
                assert_eq!((t.da, t.sa, t.fc.function()), (8, 2, RequestFunction::FdlStatus));
                assert!(t.pdu.is_empty() && t.dsap.is_none());
            }
            other => panic!("{other:?}"),
        }
        // The slave's answer: SD1, FC 0x00.
        let mut out = [0u8; 8];
        let hdr = Header { da: 2, sa: 8, fc: FunctionCode::response(ResponseStatus::Ok), dsap: None, ssap: None };
        let n = emit(&mut out, &hdr, &[]).unwrap();
        assert_eq!(&out[..n], &[0x10, 0x02, 0x08, 0x00, 0x0A, 0x16]);
    }

    #[test]
    fn golden_sd2_slave_diag_response() {
        // Diag answer from station 8 to master 2: DSAP 62, SSAP 60, 6 octets + a 1-byte block
        // (9 DU bytes → SD2; the bare 6 octets make 8 DU bytes → SD3).
        let hdr = Header { da: 2, sa: 8, fc: FunctionCode(0x08), dsap: Some(62), ssap: Some(60) };
        let mut out = [0u8; 32];
        let pdu = [0x08, 0x0C, 0x00, 0x02, 0x0F, 0x11, 0x02];
        let n = emit(&mut out, &hdr, &pdu[..7]).unwrap();
        let expect_body = [0x82, 0x88, 0x08, 0x3E, 0x3C, 0x08, 0x0C, 0x00, 0x02, 0x0F, 0x11, 0x02];
        assert_eq!(&out[..4], &[0x68, 12, 12, 0x68]);
        assert_eq!(&out[4..16], &expect_body);
        assert_eq!(out[16], fcs(&expect_body));
        assert_eq!(out[17], 0x16);
        assert_eq!(n, 18);
        match decode(&out[..n]) {
            Decoded::Frame(Telegram::Data(t), 18) => {
                assert_eq!((t.dsap, t.ssap), (Some(62), Some(60)));
                assert_eq!(t.pdu, &pdu[..7]);
            }
            other => panic!("{other:?}"),
        }
        let n = emit(&mut out, &hdr, &pdu[..6]).unwrap();
        assert_eq!((n, out[0]), (14, SD3));
    }

    #[test]
    fn sd3_for_eight_du_bytes() {
        let hdr = Header { da: 2, sa: 8, fc: FunctionCode(0x08), dsap: None, ssap: None };
        let mut out = [0u8; 32];
        let n = emit(&mut out, &hdr, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        assert_eq!((n, out[0]), (14, SD3));
        assert!(matches!(
            decode(&out[..n]),
            Decoded::Frame(Telegram::Data(DataTelegram { format: DataFormat::Sd3, .. }), 14)
        ));
    }

    #[test]
    fn token_and_sc() {
        assert_eq!(decode(&[0xDC, 0x03, 0x02]), Decoded::Frame(Telegram::Token { da: 3, sa: 2 }, 3));
        assert_eq!(decode(&[0xE5, 0x00]), Decoded::Frame(Telegram::ShortAck, 1));
    }

    #[test]
    fn header_errors() {
        assert_eq!(decode(&[0x11]), Decoded::Invalid(FrameError::UnknownStartDelimiter(0x11)));
        assert_eq!(decode(&[0x68, 3]), Decoded::Invalid(FrameError::LengthOutOfRange(3)));
        assert_eq!(decode(&[0x68, 250]), Decoded::Invalid(FrameError::LengthOutOfRange(250)));
        assert_eq!(decode(&[0x68, 5, 6]), Decoded::Invalid(FrameError::LengthMismatch { le: 5, ler: 6 }));
        assert_eq!(decode(&[0x68, 5, 5, 0x10]), Decoded::Invalid(FrameError::RepeatedSdMismatch(0x10)));
    }

    #[test]
    fn region_address_rejected() {
        let hdr = Header { da: 8, sa: 2, fc: FunctionCode(0x6C), dsap: Some(60), ssap: Some(62) };
        let mut out = [0u8; 32];
        let n = emit(&mut out, &hdr, &[]).unwrap();
        out[7] |= 0x40; // DAE b6: segment address
        finish(&mut out, n);
        assert_eq!(decode(&out[..n]), Decoded::Invalid(FrameError::RegionAddress));
        out[7] = 0x80 | 60; // DAE b7: another extension follows
        finish(&mut out, n);
        assert_eq!(decode(&out[..n]), Decoded::Invalid(FrameError::ChainedExtension));
    }

    #[test]
    fn every_prefix_is_incomplete_and_every_bit_flip_is_rejected() {
        let hdr = Header { da: 8, sa: 2, fc: FunctionCode(0x7D), dsap: None, ssap: None };
        for pdu_len in [0usize, 1, 4, 8, 32, 244] {
            let pdu: [u8; 246] = core::array::from_fn(|i| (i * 7 + 3) as u8);
            let mut out = [0u8; MAX_FRAME_LEN];
            let n = emit(&mut out, &hdr, &pdu[..pdu_len]).unwrap();
            for k in 0..n {
                assert_eq!(decode(&out[..k]), Decoded::Incomplete, "len {pdu_len} prefix {k}");
            }
            for byte in 0..n {
                for bit in 0..8 {
                    let mut f = out;
                    f[byte] ^= 1 << bit;
                    match decode(&f[..n]) {
                        Decoded::Frame(Telegram::Data(t), m) if m == n => {
                            panic!("flip {byte}.{bit} accepted as {t:?}")
                        }
                        _ => {}
                    }
                }
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn roundtrip(da in 0u8..127, sa in 0u8..127, fc: u8, dsap in proptest::option::of(0u8..64),
                     ssap in proptest::option::of(0u8..64), pdu in proptest::collection::vec(proptest::num::u8::ANY, 0..244)) {
            let hdr = Header { da, sa, fc: FunctionCode(fc), dsap, ssap };
            let mut out = [0u8; MAX_FRAME_LEN];
            let n = emit(&mut out, &hdr, &pdu).unwrap();
            proptest::prop_assert_eq!(frame_len(&out[..4]).unwrap().unwrap_or(n), n);
            match decode(&out[..n]) {
                Decoded::Frame(Telegram::Data(t), m) => {
                    proptest::prop_assert_eq!(m, n);
                    proptest::prop_assert_eq!((t.da, t.sa, t.fc.0, t.dsap, t.ssap), (da, sa, fc, dsap, ssap));
                    proptest::prop_assert_eq!(t.pdu, &pdu[..]);
                }
                other => proptest::prop_assert!(false, "{:?}", other),
            }
        }

        #[test]
        fn decode_never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..300)) {
            let _ = decode(&bytes);
            let _ = frame_len(&bytes);
        }
    }
}
