//! What this card is, as the PLC sees it: the constants that the GSD file (`gsd/ODCP0F11.gsd`)
//! declares and the firmware enforces. `host-tests/tests/gsd.rs` parses the GSD with
//! `gsd-parser` and asserts that every value here equals the GSD's — change both together.

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
pub const MAX_STATION_ADDRESS: u8 = 126;

/// GSD `MaxTsdr_<rate>`: the latest a response starts after the request's last stop bit, in
/// bit times, per rate. These are the customary standard maxima (reference §1.2); the host
/// simulator holds every response to them and the QEMU benchmark measures the real cost.
pub const fn max_tsdr(rate: Baudrate) -> u16 {
    match rate {
        Baudrate::B9600 | Baudrate::B19200 | Baudrate::B93750 | Baudrate::B187500 => 60,
        Baudrate::B45450 => 250,
        Baudrate::B500k => 100,
        Baudrate::B1500k => 150,
        Baudrate::B3M => 250,
        Baudrate::B6M => 450,
        Baudrate::B12M => 800,
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

/// GSD `Max_Input_Len` / `Max_Output_Len`: the largest cyclic images of any module.
pub const MAX_INPUT_LEN: usize = 28;
/// See [`MAX_INPUT_LEN`].
pub const MAX_OUTPUT_LEN: usize = 28;
/// GSD `Max_Module`: one drive module per configuration.
pub const MAX_MODULE: u8 = 1;

/// One cyclic-data module the card offers (a GSD `Module`): the configuration bytes Chk_Cfg
/// must carry to select it and the cyclic image sizes they imply (reference §3.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Module {
    /// GSD module name.
    pub name: &'static str,
    /// GSD module reference number (the line after `Module = ...`).
    pub reference: u16,
    /// The Cfg_Data identifier bytes (Chk_Cfg / Get_Cfg).
    pub cfg: &'static [u8],
    /// Input bytes (slave → master).
    pub inputs: u8,
    /// Output bytes (master → slave).
    pub outputs: u8,
}

/// Every module of the GSD. Standard Telegram 1 uses the special identifier format with three
/// manufacturer bytes naming the telegram (`C3 C1 C1 FD 00 01`: out 2 words, in 2 words, both
/// consistent; telegram 1), so that it cannot be confused with PPO 3 (`F1`). The PPO types
/// use the classic general identifiers of PROFIdrive 2.0 drives: PKW = `F3` (4 words in/out),
/// PZD 2/6/10 words = `F1`/`F5`/`F9` (OPTE3/E5 §6.5.4, reference §5.5).
pub const MODULES: &[Module] = &[
    Module {
        name: "Standard telegram 1, PZD-2/2",
        reference: 1,
        cfg: &[0xC3, 0xC1, 0xC1, 0xFD, 0x00, 0x01],
        inputs: 4,
        outputs: 4,
    },
    Module { name: "PPO 1, PKW + PZD-2/2", reference: 101, cfg: &[0xF3, 0xF1], inputs: 12, outputs: 12 },
    Module { name: "PPO 2, PKW + PZD-6/6", reference: 102, cfg: &[0xF3, 0xF5], inputs: 20, outputs: 20 },
    Module { name: "PPO 3, PZD-2/2", reference: 103, cfg: &[0xF1], inputs: 4, outputs: 4 },
    Module { name: "PPO 4, PZD-6/6", reference: 104, cfg: &[0xF5], inputs: 12, outputs: 12 },
    Module { name: "PPO 5, PKW + PZD-10/10", reference: 105, cfg: &[0xF3, 0xF9], inputs: 28, outputs: 28 },
    Module { name: "PPO 6, PZD-10/10", reference: 106, cfg: &[0xF9], inputs: 20, outputs: 20 },
];

/// Find the module whose configuration bytes are exactly `cfg`.
pub fn module_for_cfg(cfg: &[u8]) -> Option<&'static Module> {
    MODULES.iter().find(|m| m.cfg == cfg)
}

/// One user parameter byte of Set_Prm (a GSD `ExtUserPrmData`), located at `offset` in
/// User_Prm_Data **counted from DPV1_Status_1** (Set_Prm byte 7), as the GSD's
/// `Ext_User_Prm_Data_Ref(offset)` counts it.
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

/// Operate mode (OPTE3/E5 §5.3 Table 13): 0 = Local (drive decides), 1 = Remote PROFIdrive,
/// 2 = Remote Bypass, 3 = Remote Echo.
pub const PRM_OPERATE_MODE: UserPrm =
    UserPrm { reference: 1, offset: 3, name: "Operate mode", default: 0, min: 0, max: 3 };
/// Reaction to communication loss (watchdog, Clear, master loss) requested from the drive:
/// 0 = as configured in the drive (P0313-style), 1 = ramp stop (OFF1), 2 = coast (OFF2),
/// 3 = quick stop (OFF3), 4 = hold last setpoint.
pub const PRM_COMM_LOSS_REACTION: UserPrm =
    UserPrm { reference: 2, offset: 4, name: "Communication loss reaction", default: 0, min: 0, max: 4 };

/// All user parameters after the three DPV1 status bytes, in offset order.
pub const USER_PRMS: &[UserPrm] = &[PRM_OPERATE_MODE, PRM_COMM_LOSS_REACTION];

/// GSD `Max_User_Prm_Data_Len`: 3 DPV1 status bytes + the user parameters.
pub const USER_PRM_LEN: usize = 5;

/// The default User_Prm_Data (GSD `Ext_User_Prm_Data_Const(0)` with every default applied).
pub const USER_PRM_DEFAULTS: [u8; USER_PRM_LEN] =
    [0x00, 0x00, 0x00, PRM_OPERATE_MODE.default, PRM_COMM_LOSS_REACTION.default];
