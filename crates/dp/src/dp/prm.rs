//! Set_Prm (SAP 61): the parameterization telegram (reference §3.3).
//!
//! ```text
//! byte 0  Station_Status: b7 Lock_Req, b6 Unlock_Req, b5 Sync_Req, b4 Freeze_Req, b3 WD_On, b2..0 reserved
//! byte 1  WD_Fact_1      byte 2  WD_Fact_2      byte 3  min_TSDR (bit times, 0 = keep)
//! byte 4-5 Ident_Number (big-endian)            byte 6  Group_Ident
//! byte 7-9 DPV1_Status_1..3                     byte 10.. User_Prm_Data (the product's, SlaveConfig)
//! ```
//!
//! [`SetPrm::parse`] checks everything the slave can check against the product's
//! [`SlaveConfig`] (ident number, User_Prm_Data length and ranges, the supported features) and
//! returns the reason for a Prm_Fault ([`PrmError`]); the slave answers SC in every case
//! (reference gotcha 6).

use super::SlaveConfig;
use crate::time::{BitTimes, Duration};

/// The longest User_Prm_Data counted from DPV1_Status_1 a [`SetPrm`] holds: the Set_Prm DU
/// is at most 244 octets (reference §3.3), 7 of them standard — the protocol's maximum, so
/// any product's GSD `Max_User_Prm_Data_Len` fits (its configuration asserts it).
pub const MAX_USER_PRM_LEN: usize = 244 - 7;

/// One user parameter byte of Set_Prm (a GSD `ExtUserPrmData`), located at `offset` in
/// User_Prm_Data **counted from DPV1_Status_1** (Set_Prm byte 7), as the GSD's
/// `Ext_User_Prm_Data_Ref(offset)` counts it. [`SetPrm::parse`] refuses a value outside
/// `min..=max` ([`PrmError::UserPrm`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UserPrm {
    /// GSD `ExtUserPrmData` reference number.
    pub reference: u16,
    /// Offset in User_Prm_Data (0..2 are DPV1_Status_1..3).
    pub offset: usize,
    /// GSD text.
    pub name: &'static str,
    /// Default value (GSD).
    pub default: u8,
    /// Smallest allowed value.
    pub min: u8,
    /// Largest allowed value.
    pub max: u8,
}

/// The User_Prm_Data of an accepted Set_Prm, counted from DPV1_Status_1: exactly the GSD's
/// `Max_User_Prm_Data_Len` octets ([`SlaveConfig::user_prm_len`]), read as a byte slice.
#[derive(Clone, Copy)]
pub struct UserPrmData {
    len: u8,
    bytes: [u8; MAX_USER_PRM_LEN],
}

impl UserPrmData {
    /// `data` (at most [`MAX_USER_PRM_LEN`] octets; longer is cut).
    pub fn new(data: &[u8]) -> Self {
        let n = data.len().min(MAX_USER_PRM_LEN);
        let mut bytes = [0u8; MAX_USER_PRM_LEN];
        bytes[..n].copy_from_slice(&data[..n]);
        UserPrmData { len: n as u8, bytes }
    }

    /// The octets.
    pub fn as_slice(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len)]
    }
}

impl core::ops::Deref for UserPrmData {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        self.as_slice()
    }
}

impl core::fmt::Debug for UserPrmData {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.as_slice().fmt(f)
    }
}

impl PartialEq for UserPrmData {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl Eq for UserPrmData {}

impl<const N: usize> PartialEq<[u8; N]> for UserPrmData {
    fn eq(&self, other: &[u8; N]) -> bool {
        self.as_slice() == other
    }
}

impl PartialEq<[u8]> for UserPrmData {
    fn eq(&self, other: &[u8]) -> bool {
        self.as_slice() == other
    }
}

bitflags::bitflags! {
    /// Set_Prm byte 0, Station_Status.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct StationStatus: u8 {
        /// b7 Lock_Req.
        const LOCK_REQ = 0x80;
        /// b6 Unlock_Req.
        const UNLOCK_REQ = 0x40;
        /// b5 Sync_Req: the master will use Sync.
        const SYNC_REQ = 0x20;
        /// b4 Freeze_Req: the master will use Freeze.
        const FREEZE_REQ = 0x10;
        /// b3 WD_On: response monitoring (DP watchdog) on.
        const WD_ON = 0x08;
    }
}

bitflags::bitflags! {
    /// DPV1_Status_1 (Set_Prm byte 7).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct Dpv1Status1: u8 {
        /// b7 DPV1_Enable: acyclic services wanted.
        const DPV1_ENABLE = 0x80;
        /// b6 Fail_Safe: zero-length outputs in Clear.
        const FAIL_SAFE = 0x40;
        /// b5 Publisher_Enable (DXB, DP-V2).
        const PUBLISHER_ENABLE = 0x20;
        /// b2 WD_Base_1ms: the watchdog factors count 1 ms instead of 10 ms.
        const WD_BASE_1MS = 0x04;
    }
}

/// Why a Set_Prm was refused (→ Prm_Fault in the next diagnosis).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum PrmError {
    /// Not 7 octets + the GSD's `Max_User_Prm_Data_Len` user parameter octets (fewer or
    /// more).
    Length(usize),
    /// Reserved bits b2..b0 of Station_Status set.
    ReservedStationStatus(u8),
    /// WD_On with a factor of 0.
    WatchdogFactor,
    /// The ident number is not ours.
    Ident(u16),
    /// Sync or Freeze requested but not supported (also sets Not_Supported).
    NotSupported,
    /// A DPV1_Status bit the card does not support (DP-V1, DXB, alarms, Check_Cfg_Mode …).
    Dpv1Status {
        /// which status byte (1..=3)
        byte: u8,
        /// its value
        value: u8,
    },
    /// A user parameter outside the range the GSD defines.
    UserPrm {
        /// offset counted from DPV1_Status_1
        offset: u8,
        /// the value received
        value: u8,
    },
}

/// A checked Set_Prm.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SetPrm {
    /// Station_Status.
    pub status: StationStatus,
    /// WD_Fact_1.
    pub wd_fact_1: u8,
    /// WD_Fact_2.
    pub wd_fact_2: u8,
    /// min_TSDR, `None` when the master sent 0 ("keep").
    pub min_tsdr: Option<BitTimes>,
    /// Group_Ident.
    pub group_ident: u8,
    /// DPV1_Status_1.
    pub dpv1_status_1: Dpv1Status1,
    /// DPV1_Status_2 (kept for DP-V1).
    pub dpv1_status_2: u8,
    /// DPV1_Status_3 (kept for DP-V1).
    pub dpv1_status_3: u8,
    /// User_Prm_Data counted from DPV1_Status_1: exactly the GSD's `Max_User_Prm_Data_Len`
    /// octets ([`SlaveConfig::user_prm_len`]).
    pub user: UserPrmData,
}

/// Set_Prm byte 3, min_TSDR in bit times: `None` for 0 ("keep"); values below the FDL floor
/// of 11 bit times (reference §1.3) cannot be honoured and count as 11.
pub fn min_tsdr_of(byte: u8) -> Option<BitTimes> {
    match byte {
        0 => None,
        t => Some(BitTimes(u32::from(t.max(11)))),
    }
}

/// What a Set_Prm asks for by its Lock_Req / Unlock_Req bits (EN 50170 lock table, reference
/// §3.3 after the CP 5613 station_status table):
///
/// | Lock_Req | Unlock_Req | meaning | what the card checks |
/// |---|---|---|---|
/// | 0 | 0 | only min_TSDR is taken over, every other parameter unchanged | nothing but the length (≥ 7) |
/// | 0 | 1 | the slave is released for other masters (→ Wait_Prm) | nothing but the length |
/// | 1 | 0 | the slave is locked to this master, all parameters adopted | everything ([`SetPrm::parse`]) |
/// | 1 | 1 | the slave is released for other masters | nothing but the length |
///
/// Only Lock_Req = 1, Unlock_Req = 0 is a parameterization; the other rows are lock
/// management and are never answered with Prm_Fault (issue 12 item 4c: a locking master's
/// "min_TSDR only" telegram with another ident must not trip the drive).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum LockRequest {
    /// Lock 0 / Unlock 0: take over min_TSDR (byte 3, `None` = keep), nothing else.
    MinTsdrOnly(Option<BitTimes>),
    /// Unlock_Req set (with or without Lock_Req): release the slave.
    Unlock,
    /// Lock 1 / Unlock 0: a full parameterization, to be checked by [`SetPrm::parse`].
    Lock,
}

impl LockRequest {
    /// The request of a Set_Prm PDU; `None` when it is shorter than the 7 standard octets
    /// (a Prm_Fault, [`PrmError::Length`]).
    pub fn of(pdu: &[u8]) -> Option<LockRequest> {
        if pdu.len() < 7 {
            return None;
        }
        let status = StationStatus::from_bits_truncate(pdu[0]);
        Some(if status.contains(StationStatus::UNLOCK_REQ) {
            LockRequest::Unlock
        } else if status.contains(StationStatus::LOCK_REQ) {
            LockRequest::Lock
        } else {
            LockRequest::MinTsdrOnly(min_tsdr_of(pdu[3]))
        })
    }
}

impl SetPrm {
    /// Parse and check a Set_Prm PDU (the DU after the SAP bytes) for the product `config`:
    /// the Set_Prm ident check (bytes 4–5 = [`SlaveConfig::ident_number`], GSD
    /// `Ident_Number`), Sync_Req / Freeze_Req against `Sync_Mode_supp` / `Freeze_Mode_supp`,
    /// the DPV1_Status bits against `DPV1_Slave`, `WD_Base_1ms_supp`, `Fail_Safe` and
    /// `Diagnostic_Alarm_supp`, every [`SlaveConfig::user_prms`] range.
    ///
    /// **Length.** User_Prm_Data must have exactly the length the GSD declares
    /// (`Max_User_Prm_Data_Len` = `Ext_User_Prm_Data_Const(0)` = [`SlaveConfig::user_prm_len`]
    /// octets; a configuration tool always sends all of them): shorter or longer is
    /// [`PrmError::Length`] → Prm_Fault. This is what the ASIC slaves' firmware does: the
    /// VPC3+ / SPC3 only bound the Set_Prm buffer (7..244 octets) and hand the telegram to the
    /// firmware's check, and profichip's VPC3+ sample firmware (`DpPrm.c`,
    /// `DpPrm_ChkNewPrmData`: `bPrmLength == PRM_LEN_DPV1`, else `DP_PRM_LEN_ERROR` →
    /// "parameterization not OK"; public copy in github.com/tanyigergo/Profibus_DP_slave,
    /// `EvalBoard/DpPrm.c`) accepts the one length its GSD declares and nothing else. Issue 12
    /// item 4g: padding a short telegram with defaults would run the drive on parameters the
    /// master never chose.
    pub fn parse(pdu: &[u8], config: &SlaveConfig) -> Result<SetPrm, PrmError> {
        if pdu.len() != 7 + config.user_prm_len || config.user_prm_len > MAX_USER_PRM_LEN {
            return Err(PrmError::Length(pdu.len()));
        }
        let status_raw = pdu[0];
        if status_raw & 0x07 != 0 {
            return Err(PrmError::ReservedStationStatus(status_raw));
        }
        let status = StationStatus::from_bits_truncate(status_raw);
        let (wd_fact_1, wd_fact_2) = (pdu[1], pdu[2]);
        if status.contains(StationStatus::WD_ON) && (wd_fact_1 == 0 || wd_fact_2 == 0) {
            return Err(PrmError::WatchdogFactor);
        }
        let ident = u16::from_be_bytes([pdu[4], pdu[5]]);
        if ident != config.ident_number {
            return Err(PrmError::Ident(ident));
        }
        if (status.contains(StationStatus::SYNC_REQ) && !config.sync_mode_supp)
            || (status.contains(StationStatus::FREEZE_REQ) && !config.freeze_mode_supp)
        {
            return Err(PrmError::NotSupported);
        }
        let user = &pdu[7..];
        // DPV1_Status_1 (present: Max_User_Prm_Data_Len ≥ 3 for every DP-V1 slave;
        // missing octets read 0): what the product supports (reference §3.3).
        let status_byte = |i: usize| user.get(i).copied().unwrap_or(0);
        let (s1, s2, s3) = (status_byte(0), status_byte(1), status_byte(2));
        let mut allowed1 = 0u8;
        if config.fail_safe {
            allowed1 |= Dpv1Status1::FAIL_SAFE.bits();
        }
        if config.dpv1_slave {
            allowed1 |= Dpv1Status1::DPV1_ENABLE.bits();
        }
        if config.wd_base_1ms_supp {
            allowed1 |= Dpv1Status1::WD_BASE_1MS.bits();
        }
        if s1 & !allowed1 != 0 {
            return Err(PrmError::Dpv1Status { byte: 1, value: s1 });
        }
        // DPV1_Status_2: the alarm enables and Check_Cfg_Mode. The slave offers the diagnostic
        // alarm only (`Diagnostic_Alarm_supp`, dp::alarm), and only with DPV1_Enable; a
        // master asking for another alarm type (pull/plug, process, manufacturer, status,
        // update) or for Check_Cfg_Mode gets Prm_Fault (reference §3.3, §4.4).
        let mut allowed2 = 0u8;
        if config.diagnostic_alarm_supp && s1 & Dpv1Status1::DPV1_ENABLE.bits() != 0 {
            allowed2 |= super::alarm::ENABLE_DIAGNOSTIC_ALARM;
        }
        if s2 & !allowed2 != 0 {
            return Err(PrmError::Dpv1Status { byte: 2, value: s2 });
        }
        // DPV1_Status_3: Alarm_Mode (b2..b0) is taken (the outstanding limit, capped at
        // dp::alarm::MAX_OUTSTANDING, GSD `Alarm_Sequence_Mode_Count`); Prm_Structure,
        // IsoM_Req, PrmCmd: not supported.
        if s3 & !0x07 != 0 {
            return Err(PrmError::Dpv1Status { byte: 3, value: s3 });
        }
        for p in config.user_prms {
            let Some(&v) = user.get(p.offset) else { continue };
            if v < p.min || v > p.max {
                return Err(PrmError::UserPrm { offset: p.offset as u8, value: v });
            }
        }
        Ok(SetPrm {
            status,
            wd_fact_1,
            wd_fact_2,
            min_tsdr: min_tsdr_of(pdu[3]),
            group_ident: pdu[6],
            dpv1_status_1: Dpv1Status1::from_bits_retain(s1),
            dpv1_status_2: s2,
            dpv1_status_3: s3,
            user: UserPrmData::new(user),
        })
    }

    /// The DP watchdog time T_WD = base × WD_Fact_1 × WD_Fact_2, base 10 ms or 1 ms
    /// (WD_Base_1ms), `None` when WD_On is off (reference §1.6).
    pub fn watchdog(&self) -> Option<Duration> {
        if !self.status.contains(StationStatus::WD_ON) {
            return None;
        }
        let base_ms = if self.dpv1_status_1.contains(Dpv1Status1::WD_BASE_1MS) { 1 } else { 10 };
        Some(Duration::from_millis(base_ms * u64::from(self.wd_fact_1) * u64::from(self.wd_fact_2)))
    }
}
