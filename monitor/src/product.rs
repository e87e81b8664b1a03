//! What the monitor knows about the slaves: module and user parameter names, the ident number
//! and MaxTsdr per rate — the pbcard card's own tables (`pbcard::card`, which
//! `host-tests/tests/gsd.rs` proves equal to `gsd/ODCP0F11.gsd`), or any GSD file (`--gsd`).

use std::path::Path;

use gsd_parser::GenericStationDescription;
use pbcard::card;
use pbcard::time::Baudrate;

/// Read a GSD file with `gsd-parser` (reference §6): the one GSD loader of the project's tools —
/// the monitor's `--gsd` and `host-tests/tests/gsd.rs`. The file is ISO 8859-1 (every byte a
/// character); a file gsd-parser panics on is an error, as is one it rejects.
pub fn read_gsd(path: &Path) -> Result<GenericStationDescription, String> {
    let text = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let text: String = text.iter().map(|&b| b as char).collect();
    std::panic::catch_unwind(|| gsd_parser::parser::parse(path, &text))
        .map_err(|_| format!("{}: gsd-parser could not read the file", path.display()))?
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// The GSD's `MaxTsdr_<rate>` at `rate`, in bit times.
pub fn gsd_max_tsdr(gsd: &GenericStationDescription, rate: Baudrate) -> u16 {
    let t = &gsd.max_tsdr;
    match rate {
        Baudrate::B9600 => t.b9600,
        Baudrate::B19200 => t.b19200,
        Baudrate::B45450 => t.b45450,
        Baudrate::B93750 => t.b93750,
        Baudrate::B187500 => t.b187500,
        Baudrate::B500k => t.b500000,
        Baudrate::B1500k => t.b1500000,
        Baudrate::B3M => t.b3000000,
        Baudrate::B6M => t.b6000000,
        Baudrate::B12M => t.b12000000,
    }
}

/// A GSD module.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModuleName {
    /// GSD module name.
    pub name: String,
    /// Its Cfg_Data identifier bytes.
    pub cfg: Vec<u8>,
}

/// How a user parameter is stored in User_Prm_Data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PrmKind {
    /// An unsigned byte / word / double word (big-endian), `size` bytes.
    Unsigned(usize),
    /// A signed value of `size` bytes.
    Signed(usize),
    /// Bits `first..=last` of one byte.
    Bits(u8, u8),
}

/// A GSD `ExtUserPrmData` at its offset (counted from DPV1_Status_1, as
/// `Ext_User_Prm_Data_Ref` counts).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PrmName {
    /// Offset in User_Prm_Data.
    pub offset: usize,
    /// GSD text.
    pub name: String,
    /// Coding.
    pub kind: PrmKind,
}

impl PrmName {
    /// The value of this parameter in `user` (User_Prm_Data), if present.
    pub fn value(&self, user: &[u8]) -> Option<i64> {
        match self.kind {
            PrmKind::Unsigned(n) | PrmKind::Signed(n) => {
                let b = user.get(self.offset..self.offset + n)?;
                let mut v: i64 = 0;
                for &x in b {
                    v = (v << 8) | i64::from(x);
                }
                if matches!(self.kind, PrmKind::Signed(_)) && n < 8 {
                    let shift = 64 - 8 * n as u32;
                    v = (v << shift) >> shift;
                }
                Some(v)
            }
            PrmKind::Bits(first, last) => {
                let b = *user.get(self.offset)?;
                let width = last.saturating_sub(first).min(7) + 1;
                Some(i64::from((b >> first.min(7)) & (((1u16 << width) - 1) as u8)))
            }
        }
    }
}

/// The slave description the decoder names things by.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Product {
    /// Where the names come from ("pbcard card" or the GSD path).
    pub source: String,
    /// GSD `Ident_Number`.
    pub ident: u16,
    /// GSD modules.
    pub modules: Vec<ModuleName>,
    /// User parameters.
    pub user_prms: Vec<PrmName>,
    /// MaxTsdr per rate, in [`Baudrate::ALL`] order.
    pub max_tsdr: [u16; 10],
}

impl Product {
    /// The pbcard card (`src/card.rs`, equal to `gsd/ODCP0F11.gsd`).
    pub fn card() -> Self {
        Product {
            source: "pbcard card (gsd/ODCP0F11.gsd)".into(),
            ident: card::IDENT_NUMBER,
            modules: card::MODULES.iter().map(|m| ModuleName { name: m.name.into(), cfg: m.cfg.to_vec() }).collect(),
            user_prms: card::USER_PRMS
                .iter()
                .map(|u| PrmName { offset: u.offset, name: u.name.into(), kind: PrmKind::Unsigned(1) })
                .collect(),
            max_tsdr: Baudrate::ALL.map(card::max_tsdr),
        }
    }

    /// The names and MaxTsdr of a GSD file ([`read_gsd`]).
    pub fn from_gsd(path: &Path) -> Result<Self, String> {
        let parsed = read_gsd(path)?;
        let mut user_prms: Vec<PrmName> = parsed
            .user_prm_data
            .data_ref
            .iter()
            .map(|(offset, d)| PrmName {
                offset: *offset,
                name: d.name.trim().to_string(),
                kind: match d.data_type {
                    gsd_parser::UserPrmDataType::Unsigned8 => PrmKind::Unsigned(1),
                    gsd_parser::UserPrmDataType::Unsigned16 => PrmKind::Unsigned(2),
                    gsd_parser::UserPrmDataType::Unsigned32 => PrmKind::Unsigned(4),
                    gsd_parser::UserPrmDataType::Signed8 => PrmKind::Signed(1),
                    gsd_parser::UserPrmDataType::Signed16 => PrmKind::Signed(2),
                    gsd_parser::UserPrmDataType::Signed32 => PrmKind::Signed(4),
                    gsd_parser::UserPrmDataType::Bit(b) => PrmKind::Bits(b, b),
                    gsd_parser::UserPrmDataType::BitArea(a, b) => PrmKind::Bits(a, b),
                },
            })
            .collect();
        user_prms.sort_by_key(|p| p.offset);
        Ok(Product {
            source: path.display().to_string(),
            ident: parsed.ident_number,
            modules: parsed
                .available_modules
                .iter()
                .map(|m| ModuleName { name: m.name.trim().to_string(), cfg: m.config.clone() })
                .collect(),
            user_prms,
            max_tsdr: Baudrate::ALL.map(|r| gsd_max_tsdr(&parsed, r)),
        })
    }

    /// MaxTsdr at `rate`, in bit times.
    pub fn max_tsdr(&self, rate: Baudrate) -> u16 {
        let i = Baudrate::ALL.iter().position(|r| *r == rate).unwrap_or(0);
        self.max_tsdr[i]
    }

    /// The module whose identifier bytes are exactly `cfg`.
    pub fn module(&self, cfg: &[u8]) -> Option<&ModuleName> {
        self.modules.iter().find(|m| m.cfg == cfg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_project_gsd_equals_the_card_tables() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../gsd/ODCP0F11.gsd");
        let g = Product::from_gsd(&path).unwrap();
        let c = Product::card();
        assert_eq!(g.ident, c.ident);
        assert_eq!(g.max_tsdr, c.max_tsdr);
        assert_eq!(
            g.modules.iter().map(|m| &m.cfg).collect::<Vec<_>>(),
            c.modules.iter().map(|m| &m.cfg).collect::<Vec<_>>()
        );
        assert_eq!(g.user_prms.iter().map(|p| p.offset).collect::<Vec<_>>(), [3, 4]);
        assert!(Product::from_gsd(Path::new("/nonexistent.gsd")).is_err());
    }

    #[test]
    fn values() {
        let p = PrmName { offset: 1, name: "x".into(), kind: PrmKind::Bits(4, 6) };
        assert_eq!(p.value(&[0, 0b0101_0000]), Some(5));
        let s = PrmName { offset: 0, name: "s".into(), kind: PrmKind::Signed(2) };
        assert_eq!(s.value(&[0xFF, 0xFE]), Some(-2));
        assert_eq!(s.value(&[0xFF]), None);
    }
}
