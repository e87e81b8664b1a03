//! Chk_Cfg (SAP 62) and Get_Cfg (SAP 59): configuration identifiers (reference §3.4).
//!
//! A general identifier byte: b7 consistency, b6 word unit, b5..b4 direction (01 in, 10 out,
//! 11 in+out, 00 special format), b3..b0 length − 1. A special identifier: b7..b6 = which
//! length bytes follow (01 in, 10 out, 11 out then in), b3..b0 = manufacturer bytes that
//! follow; a length byte: b7 consistency, b6 word unit, b5..b0 length − 1.

/// One cyclic-data module a slave offers (a GSD `Module`): the Cfg_Data identifier bytes
/// Chk_Cfg must carry to select it and the cyclic image sizes they imply (reference §3.4).
/// A product lists its modules in [`super::SlaveConfig::modules`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Module {
    /// GSD module name.
    pub name: &'static str,
    /// GSD module reference number (the line after `Module = ...`); the product gives it its
    /// meaning (this card: 1 / 20 for Standard Telegram 1 / 20, 101..=106 for PPO 1..6,
    /// family tag × 1000 + telegram number for a manufacturer's telegram).
    pub reference: u16,
    /// The Cfg_Data identifier bytes (Chk_Cfg / Get_Cfg).
    pub cfg: &'static [u8],
    /// Input bytes (slave → master).
    pub inputs: u8,
    /// Output bytes (master → slave).
    pub outputs: u8,
}

/// The product's judgement of a Chk_Cfg beyond "these bytes are one of its modules": a rule
/// that ties the module to the parameterization in force (the Set_Prm User_Prm_Data), such as
/// a profile forbidding a telegram in some operate mode. The master sends Set_Prm *before*
/// Chk_Cfg, so such a pair can only be judged at Chk_Cfg, and a forbidden pair is a
/// configuration error: Cfg_Fault in the next diagnosis (reference §3.4, §3.5).
///
/// [`super::SlaveConfig::cfg_policy`] holds the product's policy; [`AcceptAll`] has no rule.
/// `Sync` because the configuration is shared by whatever task owns the slave.
pub trait CfgPolicy: Sync {
    /// Judge a Chk_Cfg whose bytes selected `module` (one of the configuration's modules),
    /// given `user_prm`, the User_Prm_Data of the accepted Set_Prm counted from DPV1_Status_1
    /// ([`super::prm::SetPrm::user`]; empty when there is none). `Err` refuses the Chk_Cfg
    /// (Cfg_Fault); the drive's telegram selection ([`super::DpSlave::require_module`]) is
    /// checked after an `Ok`. The default accepts every module.
    fn check_cfg(&self, module: &Module, user_prm: &[u8]) -> Result<(), CfgError> {
        let _ = (module, user_prm);
        Ok(())
    }
}

/// A [`CfgPolicy`] without rules: every module of the configuration is accepted whatever the
/// Set_Prm said.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AcceptAll;

impl CfgPolicy for AcceptAll {}

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
    /// The bytes are two or more of the GSD's drive modules one after the other: only one
    /// drive module is allowed (OPTE3/E5 §5.3 drive module rules; GSD `Max_Module` = 1).
    MoreThanOneDriveModule,
    /// The product's [`CfgPolicy`] does not allow the module with the Set_Prm in force (this
    /// card: Standard Telegram 20 with the operate mode Remote Bypass or Remote Echo,
    /// OPTE3/E5 §5.1.5).
    NotAllowedInOperateMode,
    /// A valid module, but not the one the drive selected (DPM `CONFIG.TELEGRAM`, taken over
    /// by [`super::DpSlave::require_module`]): the master must configure the drive's telegram
    /// (PNU 922 shows it).
    NotTheSelectedModule,
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

/// Check a Chk_Cfg against `modules` (a product's [`super::SlaveConfig::modules`]): the bytes
/// must be exactly those of one module (strict check; `Check_Cfg_Mode` is not offered). The
/// allowed combinations are OPTE3/E5 §5.3's drive module rules without safety modules:
/// exactly one drive module — none (empty or unknown bytes) is [`CfgError::Malformed`] /
/// [`CfgError::NoSuchModule`], two or more concatenated modules
/// [`CfgError::MoreThanOneDriveModule`]. Every error is a Cfg_Fault. The product's
/// [`CfgPolicy`] judges the module afterwards ([`super::DpSlave`] at Chk_Cfg).
pub fn check(cfg: &[u8], modules: &'static [Module]) -> Result<&'static Module, CfgError> {
    io_lengths(cfg)?;
    if let Some(m) = module_for_cfg(cfg, modules) {
        return Ok(m);
    }
    if splits_into_modules(cfg, modules) {
        return Err(CfgError::MoreThanOneDriveModule);
    }
    Err(CfgError::NoSuchModule)
}

/// The module of `modules` whose configuration bytes are exactly `cfg`.
pub fn module_for_cfg(cfg: &[u8], modules: &'static [Module]) -> Option<&'static Module> {
    modules.iter().find(|m| m.cfg == cfg)
}

/// Whether `cfg` is two or more of `modules` one after the other. No module's bytes start
/// with another module's (the product tests its table), so at most one module matches at
/// each position and the greedy loop is exact (and bounded: every step eats at least one
/// byte).
pub fn splits_into_modules(cfg: &[u8], modules: &[Module]) -> bool {
    let (mut rest, mut count) = (cfg, 0usize);
    while !rest.is_empty() {
        match modules.iter().find(|m| !m.cfg.is_empty() && rest.starts_with(m.cfg)) {
            Some(m) => rest = &rest[m.cfg.len()..],
            None => return false,
        }
        count += 1;
    }
    count >= 2
}
