//! Several stations in one soft slave: what each station is (`--address 5,6,7` or a TOML
//! configuration file, `--config FILE`) and the independent card each one runs — its own
//! [`Node`] (FDL station, DP state machine, DP-V1 channels) and its own [`Application`] (DPM
//! image and simulated drive).
//!
//! ```toml
//! # Defaults for every station (each optional).
//! ramp_ms = 2000          # simulated drive: ramp 0 → 100 % speed
//! verbose = false         # log every telegram of the station
//!
//! [[station]]
//! address = 5             # 0..=126, unique
//! module = "PPO 4, PZD-6/6"   # the only module Chk_Cfg may select (GSD name or reference
//!                         # number, e.g. module = 1); absent: any module of the GSD
//! ramp_ms = 1000
//! [station.params]        # initial values of the simulated drive's parameters (PNU = value)
//! 100 = 85                # P0100 acceleration time 8.5 s
//! 9900 = 7
//!
//! [[station]]
//! address = 6
//! verbose = true
//! ```
//!
//! Unknown keys, a duplicate or invalid address, an unknown module, an unknown PNU or a value
//! outside the parameter's range are a [`ConfigError`]: the binary prints it as one line and
//! exits with status 2 before it opens the serial device.

use core::fmt;
use std::collections::BTreeMap;
use std::time::Duration;

use serde::Deserialize;

use pbcard::card::{self, Module};
use pbcard::dp::DpSlave;
use pbcard::fast::{single_threaded, CoreLink, FastPath, Shared};
use pbcard::fdl::framer::{Framer, Push};
use pbcard::node::Node;
use pbcard::time::Instant;
use pbcard_sim::bench::Application;
use pbcard_sim::drive::DriveConfig;

use crate::monitor::Monitor;

/// One station of the soft slave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StationConfig {
    /// Station address.
    pub address: u8,
    /// The only module Chk_Cfg may select (`None`: any module of the GSD).
    pub module: Option<&'static Module>,
    /// Simulated drive: ramp time 0 → 100 %.
    pub ramp: Duration,
    /// Initial values of the simulated drive's parameters, `(PNU, value)`.
    pub params: Vec<(u16, i64)>,
    /// Log every telegram of this station.
    pub verbose: bool,
}

impl StationConfig {
    /// A station at `address` with the defaults of the command line.
    pub fn new(address: u8, ramp: Duration, verbose: bool) -> Self {
        StationConfig { address, module: None, ramp, params: Vec::new(), verbose }
    }
}

/// Why a station list cannot run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConfigError {
    /// The file could not be read.
    Read(String),
    /// TOML syntax, a wrong type or an unknown key (serde's message).
    Toml(String),
    /// No station at all.
    NoStation,
    /// An address outside 0..=126.
    Address(i64),
    /// Two stations with one address.
    Duplicate(u8),
    /// A module that is not in the GSD.
    Module(String),
    /// A PNU the simulated drive does not have, or a value it refuses.
    Param {
        /// the station
        address: u8,
        /// the PNU
        pnu: String,
        /// the value
        value: i64,
        /// why
        why: String,
    },
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Read(e) => write!(f, "configuration: {e}"),
            ConfigError::Toml(e) => write!(f, "configuration: {}", e.replace('\n', " ").trim()),
            ConfigError::NoStation => write!(f, "configuration: no [[station]]"),
            ConfigError::Address(a) => write!(f, "configuration: station address {a} is outside 0..=126"),
            ConfigError::Duplicate(a) => write!(f, "configuration: station address {a} is given twice"),
            ConfigError::Module(m) => {
                let names: Vec<String> =
                    card::MODULES.iter().map(|m| format!("\"{}\" ({})", m.name, m.reference)).collect();
                write!(f, "configuration: unknown module {m}; the GSD's modules are {}", names.join(", "))
            }
            ConfigError::Param { address, pnu, value, why } => {
                write!(f, "configuration: station {address}: parameter {pnu} = {value}: {why}")
            }
        }
    }
}

impl std::error::Error for ConfigError {}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    ramp_ms: Option<u64>,
    verbose: Option<bool>,
    #[serde(default)]
    station: Vec<FileStation>,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum ModuleRef {
    Reference(i64),
    Name(String),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileStation {
    address: i64,
    module: Option<ModuleRef>,
    ramp_ms: Option<u64>,
    verbose: Option<bool>,
    #[serde(default)]
    params: BTreeMap<String, i64>,
}

fn module(m: &ModuleRef) -> Result<&'static Module, ConfigError> {
    let found = match m {
        ModuleRef::Reference(r) => card::MODULES.iter().find(|x| i64::from(x.reference) == *r),
        ModuleRef::Name(n) => card::MODULES.iter().find(|x| x.name.eq_ignore_ascii_case(n.trim())),
    };
    found.ok_or_else(|| {
        ConfigError::Module(match m {
            ModuleRef::Reference(r) => r.to_string(),
            ModuleRef::Name(n) => format!("\"{n}\""),
        })
    })
}

/// Parse a configuration file's text; `ramp` and `verbose` are the defaults of the command line.
pub fn parse_config(text: &str, ramp: Duration, verbose: bool) -> Result<Vec<StationConfig>, ConfigError> {
    let f: File = toml::from_str(text).map_err(|e| ConfigError::Toml(e.message().to_string()))?;
    let ramp = f.ramp_ms.map_or(ramp, Duration::from_millis);
    let verbose = f.verbose.unwrap_or(verbose);
    let mut out = Vec::new();
    for s in &f.station {
        if !(0..=i64::from(card::MAX_STATION_ADDRESS)).contains(&s.address) {
            return Err(ConfigError::Address(s.address));
        }
        let mut params = Vec::new();
        for (k, v) in &s.params {
            match k.trim().parse::<u16>() {
                Ok(pnu) => params.push((pnu, *v)),
                Err(_) => {
                    return Err(ConfigError::Param {
                        address: s.address as u8,
                        pnu: k.clone(),
                        value: *v,
                        why: "not a parameter number".into(),
                    })
                }
            }
        }
        out.push(StationConfig {
            address: s.address as u8,
            module: s.module.as_ref().map(module).transpose()?,
            ramp: s.ramp_ms.map_or(ramp, Duration::from_millis),
            params,
            verbose: s.verbose.unwrap_or(verbose),
        });
    }
    check(&out)?;
    Ok(out)
}

/// Read and parse a configuration file.
pub fn load_config(path: &str, ramp: Duration, verbose: bool) -> Result<Vec<StationConfig>, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|e| ConfigError::Read(format!("cannot read {path}: {e}")))?;
    parse_config(&text, ramp, verbose)
}

/// The list itself: at least one station, unique addresses, and every initial parameter value
/// accepted by the simulated drive's table.
pub fn check(stations: &[StationConfig]) -> Result<(), ConfigError> {
    if stations.is_empty() {
        return Err(ConfigError::NoStation);
    }
    let mut seen = [false; 128];
    for s in stations {
        if s.address > card::MAX_STATION_ADDRESS {
            return Err(ConfigError::Address(i64::from(s.address)));
        }
        if std::mem::replace(&mut seen[usize::from(s.address)], true) {
            return Err(ConfigError::Duplicate(s.address));
        }
        Station::new(s)?;
    }
    Ok(())
}

/// A PROFIdrive error value of the drive's table, by name (VACON OPTE3/E5 Table 47).
fn param_error(v: u16) -> String {
    match v {
        0x00 => "impermissible parameter number".into(),
        0x01 => "parameter value cannot be changed".into(),
        0x02 => "low or high limit exceeded".into(),
        0x03 => "invalid subindex".into(),
        0x05 => "incorrect data type".into(),
        0x14 => "value impermissible".into(),
        v => format!("error value 0x{v:02X}"),
    }
}

/// One independent card on the shared line, with the firmware's split (`pbcard::fast`): its
/// own framer and fast path answer from the staged frames, its core (`CoreLink` + `Node`)
/// works behind them — in this single-threaded program right after each answer is decided.
#[derive(Debug)]
pub struct Station {
    /// What it is.
    pub config: StationConfig,
    /// Its framer (the line side; the node's own framer is not used).
    pub framer: Framer,
    /// The line half of the split.
    pub fast: FastPath<'static>,
    /// The core half of the split.
    pub core: CoreLink<'static>,
    /// Its protocol stack (behind the core half).
    pub node: Node,
    /// Its DPM image and simulated drive.
    pub app: Application,
    /// Its log.
    pub(crate) monitor: Monitor,
}

impl Station {
    /// Build the card of `config` (the drive's initial parameters set).
    pub fn new(config: &StationConfig) -> Result<Station, ConfigError> {
        let mut node = pbcard::card::node(DpSlave::new(&pbcard::card::SLAVE, config.address));
        node.slave_mut().require_module(config.module);
        let mut app = Application::new(DriveConfig {
            ramp_time: pbcard::time::Duration::from_micros(config.ramp.as_micros() as u64),
            ..DriveConfig::DEFAULT
        });
        for &(pnu, value) in &config.params {
            app.drive_mut().params_mut().set(pnu, 0, value).map_err(|e| ConfigError::Param {
                address: config.address,
                pnu: pnu.to_string(),
                value,
                why: format!("refused by the simulated drive ({})", param_error(e.value.0)),
            })?;
        }
        // One split per station for the life of the program.
        let shared: &'static mut Shared = Box::leak(Box::new(Shared::new()));
        let (fast, core) = shared.split(&mut node);
        Ok(Station {
            config: config.clone(),
            framer: Framer::new(),
            fast,
            core,
            node,
            app,
            monitor: Monitor::new(config.verbose, config.address),
        })
    }

    /// One received character at `now`: framed here, a telegram into the fast path (answer
    /// from the staged frames, or the core's for DP-V1), then the core works on what was
    /// queued. Returns the answer to send after min_TSDR.
    pub fn on_byte(&mut self, now: Instant, byte: u8) -> Option<Vec<u8>> {
        let Push::Frame(_) = self.framer.push(byte) else { return None };
        let mut out = [0u8; pbcard::fdl::telegram::MAX_FRAME_LEN];
        let n = single_threaded(&mut self.fast, &mut self.core, &mut self.node, now, self.framer.frame(), &mut out)?;
        Some(out[..n].to_vec())
    }

    /// Republish the staging after the node changed outside a telegram (application step,
    /// DP-V1 work, the required module); `events` from the application step.
    pub fn publish(&mut self, events: pbcard::dp::Events) {
        self.core.note_events(events);
        self.core.publish(&mut self.node);
    }

    /// The log prefix: `#5`.
    pub fn prefix(&self) -> String {
        format!("#{}", self.node.slave().address())
    }
}

/// A station's application in the main loop (`pbcard::fast::tick`): the card and its
/// simulated drive ([`Application::step`]), after which the configured module is again the only
/// one Chk_Cfg accepts (a DPM CONFIG of the simulated drive does not widen it); the card's
/// data records.
pub struct Configured<'a> {
    /// The station's card and drive.
    pub app: &'a mut Application,
    /// The configured module (`None`: any of the GSD's).
    pub module: Option<&'static Module>,
}

impl pbcard::fast::CardApp for Configured<'_> {
    type Records<'b>
        = pbcard::profile::records::WithTable<'b, pbcard::dpm::MailboxParams<'b>>
    where
        Self: 'b;
    fn step(&mut self, now: Instant, node: &mut Node) -> pbcard::dp::Events {
        let events = self.app.step(now, node);
        if self.module.is_some() {
            node.slave_mut().require_module(self.module);
        }
        events
    }
    fn records(&mut self, now: Instant) -> Self::Records<'_> {
        self.app.records(now)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const D: Duration = Duration::from_millis(2000);

    #[test]
    fn a_full_configuration() {
        let s = parse_config(
            "ramp_ms = 500\n[[station]]\naddress = 5\nmodule = \"PPO 4, PZD-6/6\"\n[station.params]\n100 = 85\n\
             [[station]]\naddress = 6\nmodule = 1\nverbose = true\nramp_ms = 100\n",
            D,
            false,
        )
        .unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(
            (s[0].address, s[0].module.map(|m| m.reference), s[0].ramp),
            (5, Some(104), Duration::from_millis(500))
        );
        assert_eq!(s[0].params, [(100, 85)]);
        assert_eq!(
            (s[1].module.map(|m| m.reference), s[1].verbose, s[1].ramp),
            (Some(1), true, Duration::from_millis(100))
        );
        let st = Station::new(&s[0]).unwrap();
        assert_eq!(st.app.drive().params().get(100, 0), Some(85));
    }

    #[test]
    fn bad_configurations_name_the_problem() {
        let e = |t: &str| parse_config(t, D, false).unwrap_err().to_string();
        assert_eq!(
            e("[[station]]\naddress = 5\n[[station]]\naddress = 5\n"),
            "configuration: station address 5 is given twice"
        );
        assert_eq!(e("[[station]]\naddress = 127\n"), "configuration: station address 127 is outside 0..=126");
        assert!(e("[[station]]\naddress = 5\nmodule = \"PPO 9\"\n")
            .starts_with("configuration: unknown module \"PPO 9\"; the GSD's modules are \"Standard telegram 1"));
        assert!(
            e("[[station]]\naddress = 5\nspeed = 3\n").contains("unknown field `speed`"),
            "{}",
            e("[[station]]\naddress = 5\nspeed = 3\n")
        );
        assert!(e("colour = 1\n").contains("unknown field `colour`"));
        assert_eq!(e(""), "configuration: no [[station]]");
        assert!(e("[[station]]\naddress = 5\n[station.params]\n100 = 100000\n")
            .starts_with("configuration: station 5: parameter 100 = 100000: refused"));
        assert!(e("[[station]]\naddress = 5\n[station.params]\n4242 = 1\n")
            .starts_with("configuration: station 5: parameter 4242 = 1: refused"));
        assert!(e("[[station]\n").starts_with("configuration: "));
        let t = "[[station]]\naddress = 5\n[station.params]\n100 = 85\n[[station]]\naddress = 5\n";
        assert!(!e(t).contains('\n'), "one line");
    }
}
