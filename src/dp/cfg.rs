//! Chk_Cfg (SAP 62) and Get_Cfg (SAP 59): configuration identifiers (reference §3.4).
//!
//! A general identifier byte: b7 consistency, b6 word unit, b5..b4 direction (01 in, 10 out,
//! 11 in+out, 00 special format), b3..b0 length − 1. A special identifier: b7..b6 = which
//! length bytes follow (01 in, 10 out, 11 out then in), b3..b0 = manufacturer bytes that
//! follow; a length byte: b7 consistency, b6 word unit, b5..b0 length − 1.

use crate::card::{self, Module};

/// Why a Chk_Cfg was refused (→ Cfg_Fault).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum CfgError {
    /// Empty or malformed identifier list (a special identifier missing its length or
    /// manufacturer bytes, or data longer than 244 bytes per direction).
    Malformed,
    /// Well-formed, but no module of the GSD has these bytes.
    NoSuchModule,
}

/// Input and output byte counts implied by a configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IoLengths {
    /// Input bytes (slave → master).
    pub inputs: usize,
    /// Output bytes (master → slave).
    pub outputs: usize,
}

/// Decode an identifier list into the I/O lengths it implies.
pub fn io_lengths(cfg: &[u8]) -> Result<IoLengths, CfgError> {
    let mut io = IoLengths::default();
    let mut i = 0;
    while i < cfg.len() {
        let id = cfg[i];
        i += 1;
        if id & 0x30 != 0 {
            // General identifier.
            let unit = if id & 0x40 != 0 { 2 } else { 1 };
            let len = ((id & 0x0F) as usize + 1) * unit;
            if id & 0x10 != 0 {
                io.inputs += len;
            }
            if id & 0x20 != 0 {
                io.outputs += len;
            }
        } else {
            // Special format (0x00 = free place: no length byte, no manufacturer bytes).
            if id & 0x30 != 0 {
                return Err(CfgError::Malformed);
            }
            let length_len = |b: u8| ((b & 0x3F) as usize + 1) * if b & 0x40 != 0 { 2 } else { 1 };
            let (has_out, has_in) = (id & 0x80 != 0, id & 0x40 != 0);
            if has_out {
                let b = *cfg.get(i).ok_or(CfgError::Malformed)?;
                io.outputs += length_len(b);
                i += 1;
            }
            if has_in {
                let b = *cfg.get(i).ok_or(CfgError::Malformed)?;
                io.inputs += length_len(b);
                i += 1;
            }
            let manufacturer = (id & 0x0F) as usize;
            // 15 = none follow (Chk_Cfg only); otherwise that many bytes follow.
            if manufacturer != 15 {
                if i + manufacturer > cfg.len() {
                    return Err(CfgError::Malformed);
                }
                i += manufacturer;
            }
        }
    }
    if cfg.is_empty() || io.inputs > 244 || io.outputs > 244 {
        return Err(CfgError::Malformed);
    }
    Ok(io)
}

/// Check a Chk_Cfg against the modules the card offers: the bytes must be exactly those of
/// one module (strict check; `Check_Cfg_Mode` is not offered).
pub fn check(cfg: &[u8]) -> Result<&'static Module, CfgError> {
    io_lengths(cfg)?;
    card::module_for_cfg(cfg).ok_or(CfgError::NoSuchModule)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn module_table_is_consistent() {
        for m in card::MODULES {
            let io = io_lengths(m.cfg).unwrap();
            assert_eq!((io.inputs, io.outputs), (m.inputs as usize, m.outputs as usize), "{}", m.name);
            assert_eq!(check(m.cfg), Ok(m));
        }
    }

    #[test]
    fn reference_examples() {
        assert_eq!(io_lengths(&[0xF1]), Ok(IoLengths { inputs: 4, outputs: 4 }));
        assert_eq!(io_lengths(&[0xC0, 0xC1, 0xC5]), Ok(IoLengths { inputs: 12, outputs: 4 }));
        assert_eq!(io_lengths(&[0x10, 0x20]), Ok(IoLengths { inputs: 1, outputs: 1 }));
        assert_eq!(io_lengths(&[0xC3, 0xC1]), Err(CfgError::Malformed));
        assert_eq!(io_lengths(&[]), Err(CfgError::Malformed));
        assert_eq!(check(&[0xF2]), Err(CfgError::NoSuchModule));
    }

    proptest::proptest! {
        #[test]
        fn never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..260)) {
            let _ = check(&bytes);
        }
    }
}
