//! What a product is, as the DP slave needs to know it: [`SlaveConfig`], the values its GSD
//! file declares and the slave enforces (ident number, modules, User_Prm_Data, supported
//! features, diagnosis length), with the product's Chk_Cfg rule ([`CfgPolicy`]).
//!
//! The slave's buffers are sized at compile time for the protocol's maxima
//! ([`MAX_INPUT_LEN`], [`MAX_OUTPUT_LEN`], [`super::diag::MAX_DIAG_DATA_LEN`],
//! [`super::prm::MAX_USER_PRM_LEN`]) rather than for one product, so that `dp` names no
//! product: a product's configuration asserts at compile time that it fits them
//! ([`SlaveConfig::fits`]). The price is RAM: about 1 KiB per slave more than a product
//! with short images would need.

use super::cfg::{CfgPolicy, Module};
use super::prm::{UserPrm, MAX_USER_PRM_LEN};

/// The largest input image (slave → master) the slave holds: the protocol's 244 octets per
/// direction (reference §3.4; [`super::cfg::io_lengths`] refuses more). A product's GSD
/// `Max_Input_Len` must not exceed it.
pub const MAX_INPUT_LEN: usize = 244;
/// The largest output image (master → slave) the slave holds, as [`MAX_INPUT_LEN`]; a
/// product's GSD `Max_Output_Len` must not exceed it.
pub const MAX_OUTPUT_LEN: usize = 244;

/// A product's DP slave configuration: the GSD's values that [`super::DpSlave`] checks the
/// master's telegrams against. `Copy` and made of `&'static` tables, so a product declares it
/// as a `const` (this card: `pbcard::card::SLAVE`) and the composition passes a reference to
/// [`super::DpSlave::new`].
#[derive(Clone, Copy)]
pub struct SlaveConfig {
    /// GSD `Ident_Number`: the Set_Prm ident check (Set_Prm bytes 4–5, else Prm_Fault),
    /// Set_Slave_Add's ident (else RS) and diagnosis octets 5–6.
    pub ident_number: u16,
    /// The station address after a factory reset (126, the commissioning address of
    /// Set_Slave_Add, reference §3.9), for the platform's address store.
    pub default_address: u8,
    /// Every GSD `Module`, in GSD order: a Chk_Cfg must carry exactly one module's bytes
    /// ([`super::cfg::check`]). The first is Real_Cfg (Get_Cfg) before any Chk_Cfg; must not
    /// be empty, and no module's bytes may start with another's.
    pub modules: &'static [Module],
    /// GSD `Max_User_Prm_Data_Len`: the User_Prm_Data octets counted from DPV1_Status_1 that
    /// every Set_Prm must carry (exactly; at least 3 for the DPV1_Status bytes, at most
    /// [`MAX_USER_PRM_LEN`]).
    pub user_prm_len: usize,
    /// The default User_Prm_Data (GSD `Ext_User_Prm_Data_Const(0)` with every default
    /// applied), [`Self::user_prm_len`] octets.
    pub user_prm_defaults: &'static [u8],
    /// The ranges of the user parameters (GSD `ExtUserPrmData`): Set_Prm refuses a value
    /// outside them (Prm_Fault).
    pub user_prms: &'static [UserPrm],
    /// GSD `Freeze_Mode_supp`: else a Set_Prm with Freeze_Req is refused (Not_Supported).
    pub freeze_mode_supp: bool,
    /// GSD `Sync_Mode_supp`: else a Set_Prm with Sync_Req is refused (Not_Supported).
    pub sync_mode_supp: bool,
    /// GSD `Fail_Safe`: Set_Prm may set DPV1_Status_1 Fail_Safe (zero-length Data_Exchange
    /// outputs in Clear, reference §3.7).
    pub fail_safe: bool,
    /// GSD `DPV1_Slave`: Set_Prm may set DPV1_Enable.
    pub dpv1_slave: bool,
    /// GSD `WD_Base_1ms_supp`: Set_Prm may set DPV1_Status_1 WD_Base_1ms.
    pub wd_base_1ms_supp: bool,
    /// GSD `Diagnostic_Alarm_supp`: Set_Prm may enable the diagnostic alarm (DPV1_Status_2
    /// b5, with DPV1_Enable; [`super::alarm`]).
    pub diagnostic_alarm_supp: bool,
    /// GSD `Max_Diag_Data_Len`: the whole Slave_Diag DU (6 standard octets + extended), at
    /// least 6, at most [`super::diag::MAX_DIAG_DATA_LEN`].
    pub max_diag_data_len: usize,
    /// The product's Chk_Cfg rule against the Set_Prm in force ([`super::cfg::AcceptAll`]
    /// for none).
    pub cfg_policy: &'static dyn CfgPolicy,
}

impl SlaveConfig {
    /// Room for extended diagnosis after the 6 standard octets: `Max_Diag_Data_Len` − 6.
    pub const fn max_ext_diag_len(&self) -> usize {
        self.max_diag_data_len.saturating_sub(6)
    }

    /// The module whose configuration bytes are exactly `cfg` (Chk_Cfg, strict check).
    pub fn module_for_cfg(&self, cfg: &[u8]) -> Option<&'static Module> {
        super::cfg::module_for_cfg(cfg, self.modules)
    }

    /// Whether the configuration fits the slave's compile-time buffers and is well formed:
    /// at least one module, every module's images within [`MAX_INPUT_LEN`] /
    /// [`MAX_OUTPUT_LEN`], `Max_User_Prm_Data_Len` in 3..=[`MAX_USER_PRM_LEN`] with as many
    /// defaults and every user parameter inside it, `Max_Diag_Data_Len` in
    /// 6..=[`super::diag::MAX_DIAG_DATA_LEN`]. A product asserts it at compile time
    /// (`const _: () = assert!(SLAVE.fits());`).
    pub const fn fits(&self) -> bool {
        if self.modules.is_empty()
            || self.user_prm_len < 3
            || self.user_prm_len > MAX_USER_PRM_LEN
            || self.user_prm_defaults.len() != self.user_prm_len
            || self.max_diag_data_len < 6
            || self.max_diag_data_len > super::diag::MAX_DIAG_DATA_LEN
        {
            return false;
        }
        let mut i = 0;
        while i < self.modules.len() {
            let m = &self.modules[i];
            if m.inputs as usize > MAX_INPUT_LEN || m.outputs as usize > MAX_OUTPUT_LEN {
                return false;
            }
            i += 1;
        }
        let mut i = 0;
        while i < self.user_prms.len() {
            if self.user_prms[i].offset >= self.user_prm_len {
                return false;
            }
            i += 1;
        }
        true
    }
}

impl core::fmt::Debug for SlaveConfig {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SlaveConfig")
            .field("ident_number", &self.ident_number)
            .field("default_address", &self.default_address)
            .field("modules", &self.modules.len())
            .field("user_prm_len", &self.user_prm_len)
            .field("max_diag_data_len", &self.max_diag_data_len)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::super::cfg::{self, AcceptAll, CfgError};
    use super::super::diag::DiagError;
    use super::super::prm::{PrmError, SetPrm};
    use super::super::DpSlave;
    use super::*;

    /// Another product: its own ident, one module, only the DPV1 status bytes, a short
    /// diagnosis, no Chk_Cfg rule.
    const OTHER: SlaveConfig = SlaveConfig {
        ident_number: 0x1234,
        default_address: 126,
        modules: &[Module { name: "1 byte in/out", reference: 1, cfg: &[0x30], inputs: 1, outputs: 1 }],
        user_prm_len: 3,
        user_prm_defaults: &[0, 0, 0],
        user_prms: &[],
        freeze_mode_supp: false,
        sync_mode_supp: true,
        fail_safe: false,
        dpv1_slave: false,
        wd_base_1ms_supp: false,
        diagnostic_alarm_supp: false,
        max_diag_data_len: 16,
        cfg_policy: &AcceptAll,
    };
    const _: () = assert!(OTHER.fits());

    #[test]
    fn another_product_is_checked_against_its_own_values() {
        let prm = |ident: u16, status: u8, user: &[u8]| {
            let mut v = vec![status, 1, 1, 11, (ident >> 8) as u8, ident as u8, 0];
            v.extend_from_slice(user);
            v
        };
        assert!(SetPrm::parse(&prm(0x1234, 0xA8, &[0, 0, 0]), &OTHER).is_ok());
        assert_eq!(SetPrm::parse(&prm(0x0F11, 0x88, &[0, 0, 0]), &OTHER), Err(PrmError::Ident(0x0F11)));
        assert_eq!(SetPrm::parse(&prm(0x1234, 0x88, &[0; 5]), &OTHER), Err(PrmError::Length(12)));
        assert_eq!(SetPrm::parse(&prm(0x1234, 0x98, &[0, 0, 0]), &OTHER), Err(PrmError::NotSupported));
        assert!(matches!(
            SetPrm::parse(&prm(0x1234, 0x88, &[0x80, 0, 0]), &OTHER),
            Err(PrmError::Dpv1Status { byte: 1, .. })
        ));
        assert_eq!(cfg::check(&[0x30], OTHER.modules).map(|m| m.reference), Ok(1));
        assert_eq!(cfg::check(&[0xF1], OTHER.modules), Err(CfgError::NoSuchModule));
        assert_eq!(cfg::check(&[0x30, 0x30], OTHER.modules), Err(CfgError::MoreThanOneDriveModule));

        let mut s = DpSlave::new(&OTHER, 5);
        assert_eq!(s.real_cfg().cfg, &[0x30]);
        assert_eq!(s.standard_diag().encode()[4..], [0x12, 0x34]);
        assert_eq!(s.set_ext_diag(&[0x0B; 11], true), Err(DiagError::TooLong));
        assert_eq!(s.set_ext_diag(&[0x0A, 1, 2, 3, 4, 5, 6, 7, 8, 9], true), Ok(()));
    }

    #[test]
    fn fits_refuses_what_the_buffers_cannot_hold() {
        assert!(!SlaveConfig { modules: &[], ..OTHER }.fits());
        assert!(!SlaveConfig { user_prm_len: 2, user_prm_defaults: &[0, 0], ..OTHER }.fits());
        assert!(!SlaveConfig { user_prm_len: 4, ..OTHER }.fits(), "defaults of another length");
        assert!(!SlaveConfig { max_diag_data_len: 245, ..OTHER }.fits());
        const BIG: Module = Module { name: "", reference: 2, cfg: &[0xC0, 0xFF, 0xFF], inputs: 245, outputs: 1 };
        assert!(!SlaveConfig { modules: &[BIG], ..OTHER }.fits());
    }
}
