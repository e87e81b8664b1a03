//! The GSD file `gsd/ODCP0F11.gsd` against the constants in `src/card.rs`.
//!
//! Two independent readings of the file:
//! * `gsd-parser` 0.6 (the parser behind profirust's tools) for everything it models;
//! * a small line scanner of our own for what gsd-parser ignores or does not check
//!   (keywords it skips, defaults within ranges, dangling `Prm_Text_Ref` /
//!   `Ext_User_Prm_Data_Ref`, the 8.3 file name, pyprofibus-compatible spelling).
//!
//! The key-to-constant table is in `gsd/README.md`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use gsd_parser::{GenericStationDescription, PrmBuilder, PrmValueConstraint, SupportedSpeeds, UserPrmDataType};
use pbcard::card;
use pbcard::time::Baudrate;
use pbcard_monitor::product::{gsd_max_tsdr, read_gsd};

/// The GSD file, named 4-character vendor abbreviation + ident number in hex (reference §6.1).
const GSD_FILE: &str = "ODCP0F11.gsd";
/// Placeholder vendor abbreviation ("Open Drive Card Project").
const VENDOR_ABBREVIATION: &str = "ODCP";
/// GSD revision this file is written for.
const GSD_REVISION: u8 = 5;

/// The device-related diagnosis block the firmware sends after the 6 standard octets
/// (gsd/README.md): header, drive status bits, drive fault code. Bit numbers count from the
/// first byte after the 6 standard octets, header included (reference §6.2, unverified).
/// These belong in src/card.rs once the firmware builds the block.
const DIAG_BLOCK_LEN: usize = 3;
/// `Unit_Diag_Bit(n)` numbers: byte 1 bits 0..3.
const DIAG_STATUS_BITS: [u32; 4] = [8, 9, 10, 11];
/// `Unit_Diag_Area` of the drive fault code: byte 2.
const DIAG_FAULT_CODE_AREA: (u16, u16) = (16, 23);

fn gsd_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("gsd").join(GSD_FILE)
}

fn gsd_text() -> String {
    let path = gsd_path();
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

/// Parse with gsd-parser, through the tools' GSD loader (`pbcard_monitor::product::read_gsd`).
/// gsd-parser panics (unwrap) on an `Ext_User_Prm_Data_Ref` to an undefined `ExtUserPrmData`,
/// so check that with our own scanner first for a clear message.
fn parse() -> GenericStationDescription {
    assert_refs_defined(&Scan::new(&gsd_text()));
    read_gsd(&gsd_path()).unwrap_or_else(|e| panic!("gsd-parser rejects the GSD:\n{e}"))
}

// ---------------------------------------------------------------------------------------------
// Identity, rates, services, lengths
// ---------------------------------------------------------------------------------------------

#[test]
fn identity() {
    let gsd = parse();
    assert_eq!(gsd.gsd_revision, GSD_REVISION, "GSD_Revision");
    assert_eq!(gsd.ident_number, card::IDENT_NUMBER, "Ident_Number");
    assert!(!gsd.vendor.trim().is_empty(), "Vendor_Name missing");
    assert!(!gsd.model.trim().is_empty(), "Model_Name missing");
    assert!(!gsd.revision.trim().is_empty(), "Revision missing");
    assert!(!gsd.hardware_release.trim().is_empty(), "Hardware_Release missing");
    assert!(!gsd.software_release.trim().is_empty(), "Software_Release missing");
    assert!(!gsd.implementation_type.trim().is_empty(), "Implementation_Type missing");

    // Keywords gsd-parser does not model.
    let scan = Scan::new(&gsd_text());
    assert_eq!(scan.number("Protocol_Ident"), Some(0), "Protocol_Ident = 0 (PROFIBUS DP)");
    assert_eq!(scan.number("Station_Type"), Some(0), "Station_Type = 0 (DP slave)");
    let family = scan.setting("Slave_Family").expect("Slave_Family missing");
    assert_eq!(family.split('@').next().map(str::trim), Some("1"), "Slave_Family main class 1 = drives");
}

fn gsd_rate(rate: Baudrate) -> (SupportedSpeeds, &'static str) {
    match rate {
        Baudrate::B9600 => (SupportedSpeeds::B9600, "9.6"),
        Baudrate::B19200 => (SupportedSpeeds::B19200, "19.2"),
        Baudrate::B45450 => (SupportedSpeeds::B45450, "45.45"),
        Baudrate::B93750 => (SupportedSpeeds::B93750, "93.75"),
        Baudrate::B187500 => (SupportedSpeeds::B187500, "187.5"),
        Baudrate::B500k => (SupportedSpeeds::B500000, "500"),
        Baudrate::B1500k => (SupportedSpeeds::B1500000, "1.5M"),
        Baudrate::B3M => (SupportedSpeeds::B3000000, "3M"),
        Baudrate::B6M => (SupportedSpeeds::B6000000, "6M"),
        Baudrate::B12M => (SupportedSpeeds::B12000000, "12M"),
    }
}

#[test]
fn every_rate_supported_with_card_max_tsdr() {
    let gsd = parse();
    let scan = Scan::new(&gsd_text());
    let mut all = SupportedSpeeds::empty();
    for rate in Baudrate::ALL {
        let (flag, name) = gsd_rate(rate);
        all |= flag;
        assert!(gsd.supported_speeds.contains(flag), "{name}_supp must be 1");
        assert_eq!(gsd_max_tsdr(&gsd, rate), card::max_tsdr(rate), "MaxTsdr_{name} != card::max_tsdr({rate:?})");
        // gsd-parser fills in a default for a missing MaxTsdr: require the keyword itself.
        assert_eq!(
            scan.number(&format!("MaxTsdr_{name}")),
            Some(i64::from(card::max_tsdr(rate))),
            "MaxTsdr_{name} must be written out in the GSD"
        );
    }
    // 31.25 kbit/s is MBP (PA) only; the card is RS-485.
    assert_eq!(gsd.supported_speeds, all, "only the ten RS-485 rates may be declared");
}

/// The GSD's MaxTsdr follow from the cycle model (`card::modelled_tsdr` of the measured
/// `card::budget_instructions` — per character or DMA mode —, capped by the customary value) once `card::GSD_FROM_MODEL`
/// is set (the F411 runs the split); until then they are the customary values. None is below
/// the model's floor (IDLE detection after min_TSDR).
#[test]
fn gsd_max_tsdr_follows_from_the_cycle_model() {
    let gsd = parse();
    for rate in Baudrate::ALL {
        let (_, name) = gsd_rate(rate);
        let declared = u32::from(gsd_max_tsdr(&gsd, rate));
        let model = card::modelled_tsdr(rate, card::budget_instructions(rate));
        let ceiling = u32::from(card::customary_max_tsdr(rate));
        let expect = if card::GSD_FROM_MODEL { model.min(ceiling) } else { ceiling };
        println!("MaxTsdr_{name}: declared {declared}, model {model}, customary {ceiling}");
        assert_eq!(declared, expect, "MaxTsdr_{name}: model {model}, ceiling {ceiling}");
        assert!(declared >= card::MAX_TSDR_FLOOR, "MaxTsdr_{name} = {declared} below the floor");
    }
}

#[test]
fn services_match_card() {
    let gsd = parse();
    assert_eq!(gsd.freeze_mode_supported, card::FREEZE_MODE_SUPP, "Freeze_Mode_supp");
    assert_eq!(gsd.sync_mode_supported, card::SYNC_MODE_SUPP, "Sync_Mode_supp");
    assert_eq!(gsd.fail_safe, card::FAIL_SAFE, "Fail_Safe");
    assert_eq!(gsd.auto_baud_supported, card::AUTO_BAUD_SUPP, "Auto_Baud_supp");
    assert_eq!(gsd.set_slave_addr_supported, card::SET_SLAVE_ADD_SUPP, "Set_Slave_Add_supp");

    // gsd-parser ignores these keywords: read them ourselves.
    let scan = Scan::new(&gsd_text());
    assert_eq!(scan.number("DPV1_Slave"), Some(i64::from(card::DPV1_SLAVE)), "DPV1_Slave");
    assert_eq!(scan.number("WD_Base_1ms_supp"), Some(i64::from(card::WD_BASE_1MS_SUPP)), "WD_Base_1ms_supp");
    assert_eq!(
        scan.number("Ident_Maintenance_supp"),
        Some(i64::from(card::IDENT_MAINTENANCE_SUPP)),
        "Ident_Maintenance_supp (I&M0-4 at slot 0 index 255)"
    );
    // Alarms (crates/dp/src/dp/alarm.rs): the diagnostic alarm only, Alarm_Ack on SAP 51 only.
    assert_eq!(
        scan.number("Diagnostic_Alarm_supp"),
        Some(i64::from(card::DIAGNOSTIC_ALARM_SUPP)),
        "Diagnostic_Alarm_supp"
    );
    for key in [
        "Process_Alarm_supp",
        "Pull_Plug_Alarm_supp",
        "Status_Alarm_supp",
        "Update_Alarm_supp",
        "Manufacturer_Specific_Alarm_supp",
    ] {
        assert_eq!(scan.number(key), Some(i64::from(card::OTHER_ALARMS_SUPP)), "{key}");
    }
    assert_eq!(
        scan.number("Extra_Alarm_SAP_supp"),
        Some(i64::from(card::EXTRA_ALARM_SAP_SUPP)),
        "Extra_Alarm_SAP_supp"
    );
    assert_eq!(
        scan.number("Alarm_Sequence_Mode_Count"),
        Some(card::ALARM_SEQUENCE_MODE_COUNT as i64),
        "Alarm_Sequence_Mode_Count"
    );
    assert_eq!(
        scan.number("Alarm_Type_Mode_supp"),
        Some(i64::from(card::ALARM_TYPE_MODE_SUPP)),
        "Alarm_Type_Mode_supp"
    );
    // The Set_Prm the GSD describes with every alarm the GSD offers enabled is accepted;
    // enabling one it does not offer is refused (Prm_Fault).
    let ok = pbcard::testkit::SetPrm::CARD.user([0x80, 0x20, 0x03, 0, 0]).pdu();
    assert!(
        pbcard::dp::prm::SetPrm::parse(&ok, &card::SLAVE).is_ok(),
        "DPV1_Enable + Enable_Diagnostic_Alarm + Alarm_Mode 3"
    );
    for (bit, key) in
        [(0x80u8, "Pull_Plug"), (0x40, "Process"), (0x10, "Manufacturer_Specific"), (0x08, "Status"), (0x04, "Update")]
    {
        let bad = pbcard::testkit::SetPrm::CARD.user([0x80, 0x20 | bit, 0, 0, 0]).pdu();
        assert!(
            pbcard::dp::prm::SetPrm::parse(&bad, &card::SLAVE).is_err(),
            "{key}_Alarm_supp = 0 but the card accepts it"
        );
    }
    // I&M0 ORDER_ID is the GSD's OrderNumber.
    assert_eq!(
        scan.setting("OrderNumber").map(|s| s.trim_matches('"').to_string()).as_deref(),
        Some(card::IM_ORDER_ID),
        "OrderNumber = I&M0 ORDER_ID"
    );
    assert_eq!(scan.number("C1_Read_Write_supp"), Some(i64::from(card::C1_READ_WRITE_SUPP)), "C1_Read_Write_supp");
    assert_eq!(scan.number("C1_Max_Data_Len"), Some(card::C1_MAX_DATA_LEN as i64), "C1_Max_Data_Len");
    assert_eq!(
        scan.number("C1_Response_Timeout"),
        Some(i64::from(card::C1_RESPONSE_TIMEOUT_10MS)),
        "C1_Response_Timeout"
    );
    assert_eq!(scan.number("C2_Read_Write_supp"), Some(i64::from(card::C2_READ_WRITE_SUPP)), "C2_Read_Write_supp");
    assert_eq!(scan.number("C2_Max_Data_Len"), Some(card::C2_MAX_DATA_LEN as i64), "C2_Max_Data_Len");
    assert_eq!(
        scan.number("C2_Response_Timeout"),
        Some(i64::from(card::C2_RESPONSE_TIMEOUT_10MS)),
        "C2_Response_Timeout"
    );
    assert_eq!(scan.number("C2_Max_Count_Channels"), Some(card::C2_MAX_COUNT_CHANNELS as i64), "C2_Max_Count_Channels");
    assert_eq!(
        scan.number("Max_Initiate_PDU_Length"),
        Some(card::MAX_INITIATE_PDU_LENGTH as i64),
        "Max_Initiate_PDU_Length"
    );
    assert_eq!(
        scan.number("Min_Slave_Intervall"),
        Some(i64::from(card::MIN_SLAVE_INTERVAL_100US)),
        "Min_Slave_Intervall"
    );
    if !card::DPV1_SLAVE {
        // DP-V1 is not implemented: no C1/C2/alarm keywords may promise otherwise.
        for key in scan.settings.iter().map(|s| s.key.to_ascii_lowercase()) {
            assert!(
                !(key.starts_with("c1_") || key.starts_with("c2_") || key.ends_with("_alarm_supp")),
                "DP-V1 keyword {key} in a DPV1_Slave = 0 GSD"
            );
        }
    }
}

#[test]
fn lengths_match_card() {
    let gsd = parse();
    assert_eq!(usize::from(gsd.max_diag_data_length), card::MAX_DIAG_DATA_LEN, "Max_Diag_Data_Len");
    assert!((6..=244).contains(&card::MAX_DIAG_DATA_LEN), "Max_Diag_Data_Len out of 6..=244");
    assert!(gsd.modular_station, "Modular_Station must be 1");
    assert_eq!(gsd.max_modules, card::MAX_MODULE, "Max_Module");
    assert_eq!(usize::from(gsd.max_input_length), card::MAX_INPUT_LEN, "Max_Input_Len");
    assert_eq!(usize::from(gsd.max_output_length), card::MAX_OUTPUT_LEN, "Max_Output_Len");
    assert_eq!(
        usize::from(gsd.max_data_length),
        card::MAX_INPUT_LEN + card::MAX_OUTPUT_LEN,
        "Max_Data_Len = Max_Input_Len + Max_Output_Len"
    );
    assert!(card::MAX_INPUT_LEN <= 244 && card::MAX_OUTPUT_LEN <= 244 && gsd.max_data_length <= 488);
    // The limits are the largest module (card.rs consistency).
    let max_in = card::MODULES.iter().map(|m| usize::from(m.inputs)).max().unwrap();
    let max_out = card::MODULES.iter().map(|m| usize::from(m.outputs)).max().unwrap();
    assert_eq!(card::MAX_INPUT_LEN, max_in, "card::MAX_INPUT_LEN != largest module input");
    assert_eq!(card::MAX_OUTPUT_LEN, max_out, "card::MAX_OUTPUT_LEN != largest module output");
    // Diagnosis: the device-related block fits.
    const { assert!(6 + DIAG_BLOCK_LEN <= card::MAX_DIAG_DATA_LEN) };
    assert_eq!(card::MAX_EXT_DIAG_LEN, card::MAX_DIAG_DATA_LEN - 6);
}

// ---------------------------------------------------------------------------------------------
// Modules and configuration bytes
// ---------------------------------------------------------------------------------------------

/// Input and output bytes implied by Chk_Cfg / Get_Cfg identifier bytes (reference §3.4).
fn decode_cfg(cfg: &[u8]) -> Result<(usize, usize), String> {
    fn len_of(b: u8) -> usize {
        let unit = if b & 0x40 != 0 { 2 } else { 1 };
        (usize::from(b & 0x3F) + 1) * unit
    }
    let (mut inputs, mut outputs) = (0, 0);
    let mut i = 0;
    while i < cfg.len() {
        let id = cfg[i];
        i += 1;
        if id & 0x30 != 0 {
            // General identifier: b6 words, b5..b4 direction, b3..b0 length - 1.
            let unit = if id & 0x40 != 0 { 2 } else { 1 };
            let len = (usize::from(id & 0x0F) + 1) * unit;
            match id & 0x30 {
                0x10 => inputs += len,
                0x20 => outputs += len,
                _ => {
                    inputs += len;
                    outputs += len;
                }
            }
        } else {
            // Special identifier: b7..b6 length bytes, b3..b0 manufacturer bytes.
            let manufacturer = usize::from(id & 0x0F);
            if manufacturer == 15 {
                return Err(format!("special identifier {id:#04x}: 15 manufacturer bytes is not allowed in Get_Cfg"));
            }
            let (has_out, has_in) = (id & 0x80 != 0, id & 0x40 != 0);
            // Output length byte comes first when both are present.
            if has_out {
                outputs += len_of(*cfg.get(i).ok_or("missing output length byte")?);
                i += 1;
            }
            if has_in {
                inputs += len_of(*cfg.get(i).ok_or("missing input length byte")?);
                i += 1;
            }
            if i + manufacturer > cfg.len() {
                return Err(format!("special identifier {id:#04x}: {manufacturer} manufacturer bytes missing"));
            }
            i += manufacturer;
        }
    }
    Ok((inputs, outputs))
}

#[test]
fn cfg_decoder_reference_examples() {
    assert_eq!(decode_cfg(&[0x00]), Ok((0, 0)));
    assert_eq!(decode_cfg(&[0x10]), Ok((1, 0)));
    assert_eq!(decode_cfg(&[0x20]), Ok((0, 1)));
    assert_eq!(decode_cfg(&[0xF1]), Ok((4, 4)));
    assert_eq!(decode_cfg(&[0xF3]), Ok((8, 8)));
    // out 2 words + in 6 words, each consistent (reference §3.4)
    assert_eq!(decode_cfg(&[0xC0, 0xC1, 0xC5]), Ok((12, 4)));
    assert_eq!(decode_cfg(&[0x42, 0x03, 0xAA, 0xBB]), Ok((4, 0)));
    assert!(decode_cfg(&[0xC3, 0xC1, 0xC1, 0xFD]).is_err());
    assert!(decode_cfg(&[0x4F, 0x00]).is_err());
}

#[test]
fn modules_match_card() {
    let gsd = parse();
    assert_eq!(gsd.available_modules.len(), card::MODULES.len(), "module count");
    for (g, c) in gsd.available_modules.iter().zip(card::MODULES) {
        assert_eq!(g.name, c.name, "module name");
        assert_eq!(g.reference, Some(u32::from(c.reference)), "reference number of {:?}", c.name);
        assert_eq!(g.config, c.cfg, "cfg bytes of {:?}", c.name);
        assert_eq!(
            decode_cfg(&g.config),
            Ok((usize::from(c.inputs), usize::from(c.outputs))),
            "cfg bytes of {:?} do not give Module.inputs/outputs",
            c.name
        );
        assert!(
            g.module_prm_data.data_const.is_empty() && g.module_prm_data.data_ref.is_empty(),
            "module {:?} has parameters the firmware does not know",
            c.name
        );
        assert!(card::module_for_cfg(&g.config) == Some(c), "module_for_cfg({:?})", c.name);
    }
    let names: BTreeSet<_> = card::MODULES.iter().map(|m| m.name).collect();
    let cfgs: BTreeSet<_> = card::MODULES.iter().map(|m| m.cfg).collect();
    let refs: BTreeSet<_> = card::MODULES.iter().map(|m| m.reference).collect();
    assert_eq!(names.len(), card::MODULES.len(), "duplicate module names");
    assert_eq!(cfgs.len(), card::MODULES.len(), "duplicate cfg bytes");
    assert_eq!(refs.len(), card::MODULES.len(), "duplicate module reference numbers");
}

/// The manufacturer bytes of every special-format module name its telegram (`FD <number>` for
/// a PROFIdrive standard telegram, `FE <family> <number>` for a manufacturer's), so that the
/// telegram identity of `dpm::Telegram` — family included — is in the GSD itself; the
/// general-format modules are the PPO types and the INVT frame. No module's bytes start with
/// another's (Chk_Cfg tells one module from two concatenated ones).
#[test]
fn module_bytes_name_their_telegram() {
    use pbcard::dpm::{Family, Telegram};
    let gsd = parse();
    for (g, c) in gsd.available_modules.iter().zip(card::MODULES) {
        let t = Telegram::of_module(c).unwrap_or_else(|| panic!("{:?} has no telegram", c.name));
        let cfg = &g.config;
        if cfg[0] & 0x30 == 0 {
            let lengths = usize::from(cfg[0] >> 7) + usize::from((cfg[0] >> 6) & 1);
            let m = &cfg[1 + lengths..];
            assert_eq!(m.len(), usize::from(cfg[0] & 0x0F), "{:?}", c.name);
            let named = match m {
                [0xFD, hi, lo] => Telegram::Standard(u16::from_be_bytes([*hi, *lo])),
                [0xFE, fam, hi, lo] => Telegram::Vendor(
                    Family::from_tag(*fam).unwrap_or_else(|| panic!("{:?}: family tag {fam}", c.name)),
                    u16::from_be_bytes([*hi, *lo]),
                ),
                _ => panic!("{:?}: manufacturer bytes {m:02X?}", c.name),
            };
            assert_eq!(named, t, "{:?}", c.name);
        } else {
            assert!(matches!(t, Telegram::Ppo(_) | Telegram::Vendor(Family::Invt, _)), "{:?} general format", c.name);
        }
        assert_eq!(2 * (t.pkw_words() + t.pzd_words()), usize::from(c.inputs), "{:?}", c.name);
        assert_eq!(2 * (t.pkw_words() + t.pzd_out_words()), usize::from(c.outputs), "{:?}", c.name);
        for o in card::MODULES.iter().filter(|o| o.reference != c.reference) {
            assert!(!cfg.starts_with(o.cfg), "{:?} starts with the bytes of {:?}", c.name, o.name);
        }
    }
    // Every telegram family of the brief is offered: ST1, ST20, VACON 100/101/138/139, PPO 1-6,
    // CFW500 103-108, CFW-11 100-107, INVT.
    let telegrams: BTreeSet<u16> = card::MODULES.iter().filter_map(Telegram::of_module).map(|t| t.code()).collect();
    let mut want = vec![Telegram::Standard(1), Telegram::Standard(20), Telegram::Vendor(Family::Invt, 1)];
    want.extend([100, 101, 138, 139].map(|n| Telegram::Vendor(Family::Vacon, n)));
    want.extend((1..=6).map(Telegram::Ppo));
    want.extend((103..=108).map(|n| Telegram::Vendor(Family::WegCfw500, n)));
    want.extend((100..=107).map(|n| Telegram::Vendor(Family::WegCfw11, n)));
    assert_eq!(telegrams, want.iter().map(|t| t.code()).collect(), "telegrams offered");
    assert_eq!(card::MODULES.len(), want.len());
}

// ---------------------------------------------------------------------------------------------
// User parameters
// ---------------------------------------------------------------------------------------------

#[test]
fn default_user_prm_data_equals_card_defaults() {
    let gsd = parse();
    let built = PrmBuilder::new(&gsd.user_prm_data).into_bytes();
    assert_eq!(built, card::USER_PRM_DEFAULTS, "PrmBuilder defaults != card::USER_PRM_DEFAULTS");
    // The constant part alone (what pyprofibus sends: it ignores ExtUserPrmData) too.
    assert_eq!(gsd.user_prm_data.data_const, vec![(0, card::USER_PRM_DEFAULTS.to_vec())], "Ext_User_Prm_Data_Const(0)");
    let scan = Scan::new(&gsd_text());
    assert_eq!(
        scan.number("Max_User_Prm_Data_Len"),
        Some(card::USER_PRM_LEN as i64),
        "Max_User_Prm_Data_Len (gsd-parser ignores it)"
    );
    // The three DPV1 status bytes are zero by default (no DPV1_Enable, no WD_Base_1ms).
    assert_eq!(&card::USER_PRM_DEFAULTS[..3], &[0, 0, 0]);
}

#[test]
fn ext_user_prm_data_matches_card() {
    let gsd = parse();
    let refs = &gsd.user_prm_data.data_ref;
    assert_eq!(refs.len(), card::USER_PRMS.len(), "number of Ext_User_Prm_Data_Ref");
    for p in card::USER_PRMS {
        assert!(p.min <= p.default && p.default <= p.max, "card default of {:?} out of range", p.name);
        assert!(p.offset >= 3 && p.offset < card::USER_PRM_LEN, "card offset of {:?}", p.name);
        assert_eq!(card::USER_PRM_DEFAULTS[p.offset], p.default, "USER_PRM_DEFAULTS[{}]", p.offset);
        let (_, def) = refs
            .iter()
            .find(|(off, _)| *off == p.offset)
            .unwrap_or_else(|| panic!("no Ext_User_Prm_Data_Ref({}) for {:?}", p.offset, p.name));
        assert_eq!(def.name, p.name, "ExtUserPrmData name at offset {}", p.offset);
        assert_eq!(def.data_type, UserPrmDataType::Unsigned8, "{:?} type", p.name);
        assert_eq!(def.default_value, i64::from(p.default), "{:?} default", p.name);
        assert_eq!(def.constraint, PrmValueConstraint::MinMax(p.min.into(), p.max.into()), "{:?} range", p.name);
        assert!(def.changeable && def.visible, "{:?} must be changeable and visible", p.name);
        // Every allowed value has a text and every text is an allowed value.
        let texts = def.text_ref.as_ref().unwrap_or_else(|| panic!("{:?} has no Prm_Text_Ref", p.name));
        let values: BTreeSet<i64> = texts.values().copied().collect();
        let allowed: BTreeSet<i64> = (i64::from(p.min)..=i64::from(p.max)).collect();
        assert_eq!(values, allowed, "PrmText values of {:?}", p.name);
        assert_eq!(texts.len(), allowed.len(), "duplicate value texts for {:?}", p.name);
        // Selecting the largest value through PrmBuilder writes exactly that byte.
        let mut b = PrmBuilder::new(&gsd.user_prm_data);
        b.set_prm(p.name, p.max.into());
        let mut expect = card::USER_PRM_DEFAULTS;
        expect[p.offset] = p.max;
        assert_eq!(b.as_bytes(), expect, "set_prm({:?}, {})", p.name, p.max);
    }
    // Reference numbers as in card.rs (scanner: gsd-parser drops them).
    let scan = Scan::new(&gsd_text());
    for p in card::USER_PRMS {
        assert!(
            scan.refs.iter().any(|r| r.module.is_none() && r.offset == p.offset && r.id == u32::from(p.reference)),
            "Ext_User_Prm_Data_Ref({}) = {} missing",
            p.offset,
            p.reference
        );
        assert_eq!(scan.ext_prms.get(&u32::from(p.reference)).map(|d| d.name.as_str()), Some(p.name));
    }
}

#[test]
fn prm_text_selection_by_name() {
    let gsd = parse();
    let mut b = PrmBuilder::new(&gsd.user_prm_data);
    b.set_prm_from_text(card::PRM_OPERATE_MODE.name, "Remote PROFIdrive");
    b.set_prm_from_text(card::PRM_COMM_LOSS_REACTION.name, "Hold last setpoint");
    let mut expect = card::USER_PRM_DEFAULTS;
    expect[card::PRM_OPERATE_MODE.offset] = 1;
    expect[card::PRM_COMM_LOSS_REACTION.offset] = 4;
    assert_eq!(b.as_bytes(), expect);
}

// ---------------------------------------------------------------------------------------------
// Device-related diagnosis texts
// ---------------------------------------------------------------------------------------------

#[test]
fn unit_diag_texts_match_diag_block() {
    let gsd = parse();
    let bits: Vec<u32> = gsd.unit_diag.bits.keys().copied().collect();
    assert_eq!(bits, DIAG_STATUS_BITS, "Unit_Diag_Bit numbers");
    for (bit, info) in &gsd.unit_diag.bits {
        assert!(!info.text.trim().is_empty(), "Unit_Diag_Bit({bit}) without text");
        // Never on the block header (bits 0..7) and inside the block.
        assert!(*bit >= 8 && (*bit as usize) < 8 * DIAG_BLOCK_LEN, "Unit_Diag_Bit({bit}) outside status byte");
    }
    assert!(gsd.unit_diag.not_bits.is_empty());
    assert_eq!(gsd.unit_diag.areas.len(), 1, "one Unit_Diag_Area");
    let area = &gsd.unit_diag.areas[0];
    assert_eq!((area.first, area.last), DIAG_FAULT_CODE_AREA, "Unit_Diag_Area of the fault code byte");
    assert_eq!(area.values.get(&0).map(String::as_str), Some("No fault"));
    let width = u32::from(area.last - area.first + 1);
    assert!(area.values.keys().all(|v| u32::from(*v) < (1 << width)), "Value() out of the area's bit width");
    assert!((usize::from(area.last) + 1) <= 8 * DIAG_BLOCK_LEN);
}

// ---------------------------------------------------------------------------------------------
// What gsd-parser does not check: our own scan of the text
// ---------------------------------------------------------------------------------------------

#[derive(Debug)]
struct Setting {
    line: usize,
    key: String,
    index: Option<i64>,
    value: String,
}

#[derive(Debug)]
enum Constraint {
    Range(i64, i64),
    Set(Vec<i64>),
    None,
}

#[derive(Debug)]
struct ScannedPrm {
    line: usize,
    name: String,
    data_type: String,
    default: i64,
    constraint: Constraint,
    text_ref: Option<u32>,
}

#[derive(Debug)]
struct ScannedRef {
    line: usize,
    module: Option<String>,
    offset: usize,
    id: u32,
}

#[derive(Debug)]
struct ScannedConst {
    module: Option<String>,
    offset: usize,
    len: usize,
}

/// A line-based reading of the GSD, independent of gsd-parser.
#[derive(Debug, Default)]
struct Scan {
    /// Top-level `key[(index)] = value` lines (outside every block).
    settings: Vec<Setting>,
    prm_texts: BTreeMap<u32, BTreeMap<i64, String>>,
    ext_prms: BTreeMap<u32, ScannedPrm>,
    refs: Vec<ScannedRef>,
    consts: Vec<ScannedConst>,
    /// Every string literal with its line and the keyword that introduced it.
    strings: Vec<(usize, String, String)>,
}

fn strip_comment(line: &str) -> &str {
    let mut in_quote = false;
    for (i, c) in line.char_indices() {
        match c {
            '"' => in_quote = !in_quote,
            ';' if !in_quote => return &line[..i],
            _ => {}
        }
    }
    line
}

fn parse_int(s: &str) -> Option<i64> {
    let s = s.trim();
    let (neg, digits) = match s.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, s),
    };
    let v = match digits.strip_prefix("0x") {
        Some(hex) => i64::from_str_radix(hex, 16).ok()?,
        None => digits.parse::<i64>().ok()?,
    };
    Some(if neg { -v } else { v })
}

/// `min-max` (either may be negative).
fn parse_range(s: &str) -> Option<(i64, i64)> {
    let s = s.trim();
    let split = s
        .char_indices()
        .skip(1)
        .find(|&(i, c)| c == '-' && s[..i].trim_end().ends_with(|p: char| p.is_ascii_hexdigit()))?
        .0;
    Some((parse_int(&s[..split])?, parse_int(&s[split + 1..])?))
}

/// `key[(index)] = value`.
fn split_setting(line: &str) -> Option<(String, Option<i64>, String)> {
    let (lhs, value) = line.split_once('=')?;
    let lhs = lhs.trim();
    let (key, index) = match lhs.split_once('(') {
        Some((k, rest)) => (k.trim(), Some(parse_int(rest.trim_end_matches(')').trim())?)),
        None => (lhs, None),
    };
    Some((key.to_string(), index, value.trim().to_string()))
}

fn string_literal(value: &str) -> Option<String> {
    let v = value.trim();
    let start = v.find('"')?;
    let end = v[start + 1..].find('"')? + start + 1;
    Some(v[start + 1..end].to_string())
}

impl Scan {
    fn new(text: &str) -> Scan {
        // Join `\` continuation lines, keep the first line number.
        let mut lines: Vec<(usize, String)> = Vec::new();
        let mut continued = false;
        for (n, raw) in text.lines().enumerate() {
            let l = strip_comment(raw).trim_end().to_string();
            let (body, cont) = match l.strip_suffix('\\') {
                Some(b) => (b.to_string(), true),
                None => (l, false),
            };
            if continued {
                lines.last_mut().unwrap().1.push_str(&body);
            } else {
                lines.push((n + 1, body));
            }
            continued = cont;
        }
        let start = lines.iter().position(|(_, l)| l.trim() == "#Profibus_DP").expect("no #Profibus_DP line");

        let mut scan = Scan::default();
        enum Block {
            Top,
            PrmText(u32),
            ExtPrm(u32, bool),
            Module(String),
            DiagArea,
            Other(&'static str),
        }
        let mut block = Block::Top;
        for (n, line) in lines.into_iter().skip(start + 1) {
            let line = line.trim();
            if line.is_empty() {
                continue;
            }
            let lower = line.to_ascii_lowercase();
            let setting = split_setting(line);
            if let Some((key, _, value)) = &setting {
                if let Some(s) = string_literal(value) {
                    scan.strings.push((n, key.clone(), s));
                }
            }
            match &mut block {
                Block::Top => {
                    let Some((key, index, value)) = setting else {
                        match lower.as_str() {
                            "slotdefinition" => block = Block::Other("endslotdefinition"),
                            _ => panic!("line {n}: unexpected {line:?}"),
                        }
                        continue;
                    };
                    match key.to_ascii_lowercase().as_str() {
                        "prmtext" => {
                            let id = parse_int(&value).expect("PrmText number") as u32;
                            assert!(
                                scan.prm_texts.insert(id, BTreeMap::new()).is_none(),
                                "line {n}: PrmText {id} twice"
                            );
                            block = Block::PrmText(id);
                        }
                        "extuserprmdata" => {
                            let (id, name) = value.split_once('"').expect("ExtUserPrmData = id \"name\"");
                            let id = parse_int(id).expect("ExtUserPrmData number") as u32;
                            let name = name.trim_end().trim_end_matches('"').to_string();
                            let def = ScannedPrm {
                                line: n,
                                name,
                                data_type: String::new(),
                                default: 0,
                                constraint: Constraint::None,
                                text_ref: None,
                            };
                            assert!(scan.ext_prms.insert(id, def).is_none(), "line {n}: ExtUserPrmData {id} twice");
                            block = Block::ExtPrm(id, false);
                        }
                        "module" => {
                            let name = string_literal(&value).expect("Module name");
                            block = Block::Module(name);
                        }
                        "unit_diag_area" => block = Block::DiagArea,
                        "unitdiagtype" => block = Block::Other("endunitdiagtype"),
                        "physical_interface" => block = Block::Other("end_physical_interface"),
                        _ => scan.add_setting(None, n, key, index, value),
                    }
                }
                Block::PrmText(id) => {
                    if lower == "endprmtext" {
                        block = Block::Top;
                        continue;
                    }
                    let (key, index, value) = setting.unwrap_or_else(|| panic!("line {n}: {line:?} in PrmText"));
                    assert!(key.eq_ignore_ascii_case("text"), "line {n}: {key} in PrmText");
                    let index = index.expect("Text(value)");
                    let text = string_literal(&value).expect("Text string");
                    let texts = scan.prm_texts.get_mut(id).unwrap();
                    assert!(texts.insert(index, text).is_none(), "line {n}: Text({index}) twice");
                }
                Block::ExtPrm(id, typed) => {
                    let def = scan.ext_prms.get_mut(id).unwrap();
                    if lower == "endextuserprmdata" {
                        assert!(*typed, "line {n}: ExtUserPrmData {id} without a type line");
                        block = Block::Top;
                    } else if !*typed {
                        let mut parts = line.split_whitespace();
                        def.data_type = parts.next().unwrap().to_string();
                        def.default = parse_int(parts.next().expect("default value")).expect("default value");
                        let rest: String = parts.collect();
                        def.constraint = if rest.is_empty() {
                            Constraint::None
                        } else if rest.contains(',') || parse_int(&rest).is_some() {
                            Constraint::Set(rest.split(',').map(|v| parse_int(v).expect("value set")).collect())
                        } else {
                            let (lo, hi) = parse_range(&rest).unwrap_or_else(|| panic!("line {n}: range {rest:?}"));
                            Constraint::Range(lo, hi)
                        };
                        *typed = true;
                    } else {
                        let (key, _, value) = setting.unwrap_or_else(|| panic!("line {n}: {line:?} in ExtUserPrmData"));
                        match key.to_ascii_lowercase().as_str() {
                            "prm_text_ref" => def.text_ref = Some(parse_int(&value).expect("Prm_Text_Ref") as u32),
                            "changeable" | "visible" => {}
                            _ => panic!("line {n}: {key} in ExtUserPrmData"),
                        }
                    }
                }
                Block::Module(name) => {
                    if lower == "endmodule" {
                        block = Block::Top;
                    } else if let Some((key, index, value)) = setting {
                        let module = Some(name.clone());
                        scan.add_setting(module, n, key, index, value);
                    }
                }
                Block::DiagArea => {
                    if lower == "unit_diag_area_end" {
                        block = Block::Top;
                    }
                }
                Block::Other(end) => {
                    if lower == *end {
                        block = Block::Top;
                    }
                }
            }
        }
        assert!(matches!(block, Block::Top), "unterminated block at end of file");
        scan
    }

    fn add_setting(&mut self, module: Option<String>, line: usize, key: String, index: Option<i64>, value: String) {
        match key.to_ascii_lowercase().as_str() {
            "ext_user_prm_data_ref" => self.refs.push(ScannedRef {
                line,
                module,
                offset: index.expect("Ext_User_Prm_Data_Ref(offset)") as usize,
                id: parse_int(&value).expect("Ext_User_Prm_Data_Ref value") as u32,
            }),
            "ext_user_prm_data_const" => self.consts.push(ScannedConst {
                module,
                offset: index.expect("Ext_User_Prm_Data_Const(offset)") as usize,
                len: value.split(',').inspect(|v| assert!(parse_int(v).is_some(), "line {line}: byte {v:?}")).count(),
            }),
            _ if module.is_none() => self.settings.push(Setting { line, key, index, value }),
            _ => {}
        }
    }

    /// The value of the one top-level setting `key` (case-insensitive).
    fn setting(&self, key: &str) -> Option<&str> {
        let found: Vec<_> =
            self.settings.iter().filter(|s| s.key.eq_ignore_ascii_case(key) && s.index.is_none()).collect();
        let lines: Vec<usize> = found.iter().map(|s| s.line).collect();
        assert!(found.len() <= 1, "{key} given more than once, lines {lines:?}");
        found.first().map(|s| s.value.as_str())
    }

    fn number(&self, key: &str) -> Option<i64> {
        self.setting(key).map(|v| parse_int(v).unwrap_or_else(|| panic!("{key} = {v:?} is not a number")))
    }
}

fn type_range(data_type: &str) -> Option<(i64, i64, usize)> {
    let t = data_type.to_ascii_lowercase();
    Some(match t.as_str() {
        "unsigned8" => (0, 0xFF, 1),
        "unsigned16" => (0, 0xFFFF, 2),
        "unsigned32" => (0, 0xFFFF_FFFF, 4),
        "signed8" => (-128, 127, 1),
        "signed16" => (-32768, 32767, 2),
        "signed32" => (-(1 << 31), (1 << 31) - 1, 4),
        _ if t.starts_with("bitarea(") => {
            let (first, last) = parse_range(t.trim_start_matches("bitarea(").trim_end_matches(')'))?;
            assert!(0 <= first && first <= last && last <= 7, "{data_type}");
            (0, (1 << (last - first + 1)) - 1, 1)
        }
        _ if t.starts_with("bit(") => {
            let bit = parse_int(t.trim_start_matches("bit(").trim_end_matches(')'))?;
            assert!((0..=7).contains(&bit), "{data_type}");
            (0, 1, 1)
        }
        _ => return None,
    })
}

fn assert_refs_defined(scan: &Scan) {
    for r in &scan.refs {
        assert!(
            scan.ext_prms.contains_key(&r.id),
            "line {}: Ext_User_Prm_Data_Ref({}) = {} but no ExtUserPrmData {} is defined",
            r.line,
            r.offset,
            r.id,
            r.id
        );
        // gsd-parser resolves references in file order.
        assert!(
            scan.ext_prms[&r.id].line < r.line,
            "line {}: ExtUserPrmData {} must be defined before use",
            r.line,
            r.id
        );
    }
}

#[test]
fn every_ext_user_prm_data_ref_points_to_a_definition() {
    let scan = Scan::new(&gsd_text());
    assert!(!scan.refs.is_empty());
    assert_refs_defined(&scan);
    let used: BTreeSet<u32> = scan.refs.iter().map(|r| r.id).collect();
    let defined: BTreeSet<u32> = scan.ext_prms.keys().copied().collect();
    assert_eq!(used, defined, "ExtUserPrmData defined but never referenced");
}

#[test]
fn every_prm_text_ref_is_defined() {
    let scan = Scan::new(&gsd_text());
    for (id, def) in &scan.ext_prms {
        if let Some(t) = def.text_ref {
            assert!(
                scan.prm_texts.contains_key(&t),
                "ExtUserPrmData {id} ({:?}): Prm_Text_Ref = {t} undefined",
                def.name
            );
        }
    }
}

#[test]
fn defaults_and_texts_within_ranges() {
    let scan = Scan::new(&gsd_text());
    assert!(!scan.ext_prms.is_empty());
    for (id, def) in &scan.ext_prms {
        let what = format!("line {}: ExtUserPrmData {id} ({:?})", def.line, def.name);
        let (tmin, tmax, _) =
            type_range(&def.data_type).unwrap_or_else(|| panic!("{what}: unknown type {:?}", def.data_type));
        let allowed = |v: i64| {
            (tmin..=tmax).contains(&v)
                && match &def.constraint {
                    Constraint::Range(lo, hi) => (lo..=hi).contains(&&v),
                    Constraint::Set(set) => set.contains(&v),
                    Constraint::None => true,
                }
        };
        if let Constraint::Range(lo, hi) = def.constraint {
            assert!(lo <= hi && tmin <= lo && hi <= tmax, "{what}: range {lo}-{hi} outside {}", def.data_type);
        }
        assert!(allowed(def.default), "{what}: default {} outside its range", def.default);
        if let Some(texts) = def.text_ref.and_then(|t| scan.prm_texts.get(&t)) {
            for v in texts.keys() {
                assert!(allowed(*v), "{what}: Text({v}) is not an allowed value");
            }
            assert!(texts.contains_key(&def.default), "{what}: default {} has no text", def.default);
        }
    }
}

#[test]
fn user_prm_bytes_fit_max_user_prm_data_len() {
    let scan = Scan::new(&gsd_text());
    let max = scan.number("Max_User_Prm_Data_Len").expect("Max_User_Prm_Data_Len missing") as usize;
    assert!(max <= 237, "Max_User_Prm_Data_Len > 237");
    let mut covered = vec![false; max];
    for c in scan.consts.iter().filter(|c| c.module.is_none()) {
        assert!(c.offset + c.len <= max, "Ext_User_Prm_Data_Const({}) of {} bytes exceeds {max}", c.offset, c.len);
        covered[c.offset..c.offset + c.len].iter_mut().for_each(|b| *b = true);
    }
    assert!(
        covered.iter().all(|b| *b),
        "Ext_User_Prm_Data_Const must give every byte a default (pyprofibus sends only these)"
    );
    for r in scan.refs.iter().filter(|r| r.module.is_none()) {
        let (_, _, size) = type_range(&scan.ext_prms[&r.id].data_type).unwrap();
        assert!(
            r.offset + size <= max,
            "line {}: Ext_User_Prm_Data_Ref({}) beyond Max_User_Prm_Data_Len",
            r.line,
            r.offset
        );
        // Offsets 0..2 are the DPV1 status bytes, not device parameters.
        assert!(r.offset >= 3, "line {}: parameter inside DPV1_Status_1..3", r.line);
    }
}

#[test]
fn file_name_is_vendor_abbreviation_plus_ident() {
    let path = gsd_path();
    let stem = path.file_stem().unwrap().to_str().unwrap();
    let ext = path.extension().unwrap().to_str().unwrap();
    assert_eq!(ext.to_ascii_lowercase(), "gsd", "default-language GSD extension");
    assert_eq!(stem.len(), 8, "8.3 file name");
    assert_eq!(&stem[..4], VENDOR_ABBREVIATION);
    assert!(VENDOR_ABBREVIATION.chars().all(|c| c.is_ascii_alphanumeric()) && VENDOR_ABBREVIATION.len() == 4);
    assert_eq!(stem[4..].to_ascii_uppercase(), format!("{:04X}", card::IDENT_NUMBER), "file name must carry the ident");
    // No stale GSD for another ident lies next to it.
    let others: Vec<_> = std::fs::read_dir(path.parent().unwrap())
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.to_ascii_lowercase().ends_with(".gsd") && *n != GSD_FILE)
        .collect();
    assert!(others.is_empty(), "other GSD files in gsd/: {others:?}");
}

/// pyprofibus 1.13 reads GSDs with case-sensitive regular expressions and silently skips
/// lines it cannot match; keep the file in the subset both parsers read identically.
#[test]
fn text_is_pyprofibus_friendly() {
    let text = gsd_text();
    assert!(text.is_ascii(), "GSD must be plain ASCII");
    assert!(!text.contains("0X"), "hex numbers need a lowercase 0x prefix (both parsers)");
    let lines: Vec<&str> = text.lines().collect();
    let start = lines.iter().position(|l| *l == "#Profibus_DP").expect("a line exactly \"#Profibus_DP\"");
    for (n, l) in lines.iter().enumerate().skip(start + 1) {
        assert!(!l.starts_with('#'), "line {}: pyprofibus ends the GSD at a line starting with '#'", n + 1);
    }

    // Characters pyprofibus accepts inside a string literal (its _reStr), minus ';' which its
    // comment stripper may treat as a comment start.
    let ok = |c: char| c.is_ascii_alphanumeric() || " ._-+*/<>()[]{}!$%&?^|=#,:`".contains(c);
    let scan = Scan::new(&text);
    assert!(!scan.strings.is_empty());
    for (n, key, s) in &scan.strings {
        assert!(!s.is_empty(), "line {n}: empty string");
        assert!(s.chars().all(ok), "line {n}: {key} = {s:?} has characters pyprofibus rejects");
        let limit = if key.eq_ignore_ascii_case("info_text") { 256 } else { 32 };
        assert!(s.len() <= limit, "line {n}: {key} = {s:?} longer than {limit}");
    }
    for line in text.lines() {
        // pyprofibus treats the character after a closing quote as quoted: `"x";` hides the ';'.
        let code = strip_comment(line);
        if code.len() < line.len() && code.ends_with('"') {
            panic!("{line:?}: put a space between a string and its ';' comment");
        }
    }

    // Keywords pyprofibus knows must be spelled exactly its way.
    #[rustfmt::skip]
    const PYPROFIBUS_KEYWORDS: &[&str] = &[
        "GSD_Revision", "Ident_Number", "Protocol_Ident", "Station_Type", "Repeater_Ctrl_Sig",
        "24V_Pins", "Min_Slave_Intervall", "Max_Diag_Data_Len", "Modul_Offset", "Max_Module",
        "Max_Input_Len", "Max_Output_Len", "Max_Data_Len", "MaxTsdr_9.6", "MaxTsdr_19.2",
        "MaxTsdr_45.45", "MaxTsdr_93.75", "MaxTsdr_187.5", "MaxTsdr_500", "MaxTsdr_1.5M",
        "MaxTsdr_3M", "MaxTsdr_6M", "MaxTsdr_12M", "User_Prm_Data_Len", "Max_User_Prm_Data_Len",
        "Freeze_Mode_supp", "Sync_Mode_supp", "Set_Slave_Add_supp", "Redundancy", "Fail_Safe",
        "Modular_Station", "Auto_Baud_supp", "9.6_supp", "19.2_supp", "45.45_supp", "93.75_supp",
        "187.5_supp", "500_supp", "1.5M_supp", "3M_supp", "6M_supp", "12M_supp",
        "FixPresetModules", "DPV1_Slave", "Vendor_Name", "Model_Name", "Revision",
        "Hardware_Release", "Software_Release", "Implementation_Type", "Bitmap_Device",
        "Bitmap_SF", "OrderNumber", "PrmText", "Slave_Family", "User_Prm_Data", "ExtUserPrmData",
        "Ext_User_Prm_Data_Const", "Ext_User_Prm_Data_Ref", "Module", "Text", "Prm_Text_Ref",
        "Ext_Module_Prm_Data_Len", "Preset", "EndPrmText", "EndExtUserPrmData", "EndModule",
    ];
    for (n, line) in text.lines().enumerate().skip(start + 1) {
        let code = strip_comment(line).trim();
        let word = code.split(|c: char| c == '=' || c == '(' || c.is_whitespace()).next().unwrap_or("");
        if let Some(k) = PYPROFIBUS_KEYWORDS.iter().find(|k| k.eq_ignore_ascii_case(word)) {
            assert_eq!(word, *k, "line {}: pyprofibus only reads the spelling {k}", n + 1);
        }
    }
}

/// No GSD keyword names the application profile, so the GSD states it in a comment next to
/// `Slave_Family = 1@Drives`; the MSAC_C2 Initiate.res answers that Profile_Ident_Number
/// (`card::PROFILE_IDENT_NUMBER`, issue 12 item 4k).
#[test]
fn profile_ident_is_the_gsds_profidrive() {
    let text = gsd_text();
    let line = text
        .lines()
        .find(|l| l.starts_with("; Profile: PROFIdrive"))
        .expect("a comment line \"; Profile: PROFIdrive ..., Profile_Ident_Number 0x....\"");
    let ident = line
        .split("Profile_Ident_Number")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(parse_int)
        .unwrap_or_else(|| panic!("no Profile_Ident_Number in {line:?}"));
    assert_eq!(ident, i64::from(card::PROFILE_IDENT_NUMBER));
    assert_eq!(Scan::new(&text).setting("Slave_Family"), Some("1@Drives"));
}

/// The GSD's `SlotDefinition` puts the drive module in slot `card::DRIVE_MODULE_SLOT`, every
/// module allowed there and Standard telegram 1 the default; records 47 / 48 answer at the
/// device's slot 0 and there (`card::RECORD_SLOTS`, issue 12 item 4j).
#[test]
fn slot_definition_is_the_drive_module_slot() {
    let gsd = parse();
    assert_eq!(gsd.slots.len(), 1, "one slot: {:?}", gsd.slots);
    let slot = &gsd.slots[0];
    assert_eq!(slot.number, card::DRIVE_MODULE_SLOT);
    assert_eq!(slot.default.reference, Some(u32::from(card::MODULES[0].reference)));
    assert_eq!(slot.allowed_modules.len(), gsd.available_modules.len(), "every module allowed in the slot");
    assert_eq!(card::RECORD_SLOTS, [0, card::DRIVE_MODULE_SLOT]);
}
