//! Command-line flags.

use core::fmt;
use std::time::Duration;

use pbcard::card;
use pbcard::time::Baudrate;

/// The help text.
pub const USAGE: &str = "\
pbcard-softslave — a PROFIBUS DP slave with a simulated AC drive behind it, on a serial port.
The same protocol stack as the pbcard option card firmware; the PLC configures it with the
card's GSD (gsd/ODCP0F11.gsd) and may choose any of its modules (Chk_Cfg decides).

USAGE:
    pbcard-softslave --device PATH [--baud N] [--address N] [options]

OPTIONS:
    -d, --device PATH   serial device: a USB-RS485 adapter (/dev/ttyUSB0, set to 8E1) or a
                        pseudo-terminal (/dev/pts/N, 8N1: a pty cannot do parity).
                        `--device pty` creates a pseudo-terminal and prints its path.
    -b, --baud N        PROFIBUS rate in bit/s: 9600 19200 45450 93750 187500 500000 1500000
                        3000000 6000000 12000000 (also 19.2k, 1.5M …). Default 19200.
    -a, --address N     station address 0..=126, or several: 5,6,7 (one independent card
                        each: DP state, DP-V1 channels, simulated drive). Default 126.
    -c, --config FILE   the stations from a TOML file (per station: address, module, ramp,
                        initial drive parameters, verbose; README, Soft slave). A bad file
                        is one error line and exit status 2, before the device is opened.
    -s, --state FILE    keep the station address (Set_Slave_Add) and I&M1-4 across restarts in
                        FILE (created when missing; several stations: FILE.<address> each).
                        A stored address replaces --address / the configured one.
        --ramp-ms N     simulated drive: ramp time from 0 to 100 % speed. Default 2000.
        --pd-every S    log the process data every S seconds (0 = never). Default 2.
        --idle-us N     silence after which a partial telegram is dropped. Default: 33 bit
                        times, at least 10000 µs (USB adapters deliver telegrams in pieces).
    -v, --verbose       log every telegram in hex.
    -h, --help          this text.
    -V, --version       the version.

Stop with Ctrl-C.
";

/// What the soft slave runs with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Options {
    /// Serial device path, or `pty` to create a pseudo-terminal.
    pub device: String,
    /// Transmission rate.
    pub baud: Baudrate,
    /// Station address (the first of [`Options::addresses`]).
    pub address: u8,
    /// Further station addresses of `--address 5,6,7` (after `address`).
    pub more_addresses: Vec<u8>,
    /// `--config FILE`: the stations from a TOML file (overrides the address list).
    pub config: Option<String>,
    /// `--state FILE`: the address and I&M1–4 kept across restarts ([`crate::state`]).
    pub state: Option<String>,
    /// Simulated drive: ramp time 0 → 100 %.
    pub ramp: Duration,
    /// Process-data log period (`None` = never).
    pub pd_every: Option<Duration>,
    /// Idle threshold override.
    pub idle: Option<Duration>,
    /// Log every telegram.
    pub verbose: bool,
}

impl Options {
    /// Defaults for `device`.
    pub fn new(device: impl Into<String>) -> Self {
        Options {
            device: device.into(),
            baud: Baudrate::B19200,
            address: card::DEFAULT_ADDRESS,
            more_addresses: Vec::new(),
            config: None,
            state: None,
            ramp: Duration::from_millis(2000),
            pd_every: Some(Duration::from_secs(2)),
            idle: None,
            verbose: false,
        }
    }
}

impl Options {
    /// The stations to run: from `--config`, else one per address of `--address` with the
    /// command line's ramp and verbosity. Checked: unique addresses, known modules, initial
    /// parameter values the simulated drive accepts.
    pub fn stations(&self) -> Result<Vec<crate::station::StationConfig>, crate::station::ConfigError> {
        if let Some(path) = &self.config {
            return crate::station::load_config(path, self.ramp, self.verbose);
        }
        let list: Vec<crate::station::StationConfig> = std::iter::once(self.address)
            .chain(self.more_addresses.iter().copied())
            .map(|a| crate::station::StationConfig::new(a, self.ramp, self.verbose))
            .collect();
        crate::station::check(&list)?;
        Ok(list)
    }
}

/// What the command line asks for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Command {
    /// Run the slave.
    Run(Options),
    /// Print [`USAGE`].
    Help,
    /// Print the version.
    Version,
}

/// A command line that cannot be run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ArgError {
    /// A flag nobody knows.
    Unknown(String),
    /// A flag without its value.
    MissingValue(&'static str),
    /// A value that does not fit the flag.
    Invalid {
        /// the flag
        flag: &'static str,
        /// the value given
        value: String,
        /// what is expected
        expected: &'static str,
    },
    /// `--device` is required.
    NoDevice,
}

impl fmt::Display for ArgError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ArgError::Unknown(a) => write!(f, "unknown argument '{a}'"),
            ArgError::MissingValue(flag) => write!(f, "{flag} needs a value"),
            ArgError::Invalid { flag, value, expected } => write!(f, "{flag} '{value}': expected {expected}"),
            ArgError::NoDevice => write!(f, "--device PATH is required (a serial device, or 'pty')"),
        }
    }
}

impl std::error::Error for ArgError {}

const RATES: &str = "one of 9600 19200 45450 93750 187500 500000 1500000 3000000 6000000 12000000 (or 19.2k, 1.5M …)";

/// A PROFIBUS rate from `19200`, `19.2k`, `1.5M`, `45.45k` … (exact values only).
pub fn parse_baud(s: &str) -> Option<Baudrate> {
    let s = s.trim();
    let (num, mult) = match s.char_indices().last()? {
        (i, 'k' | 'K') => (&s[..i], 1_000u64),
        (i, 'M') => (&s[..i], 1_000_000u64),
        _ => (s, 1u64),
    };
    let (int, frac) = num.split_once('.').unwrap_or((num, ""));
    if int.is_empty()
        || int.len() > 9
        || frac.len() > 6
        || !(int.bytes().chain(frac.bytes()).all(|b| b.is_ascii_digit()))
    {
        return None;
    }
    let scale = 10u64.pow(frac.len() as u32);
    let whole: u64 = int.parse().ok()?;
    let part: u64 = if frac.is_empty() { 0 } else { frac.parse().ok()? };
    let scaled = (whole * scale + part) * mult;
    if !scaled.is_multiple_of(scale) {
        return None;
    }
    let bps = scaled / scale;
    Baudrate::ALL.into_iter().find(|r| r.bits_per_second() as u64 == bps)
}

fn parse_u64(flag: &'static str, value: &str, max: u64, expected: &'static str) -> Result<u64, ArgError> {
    match value.parse::<u64>() {
        Ok(v) if v <= max => Ok(v),
        _ => Err(ArgError::Invalid { flag, value: value.to_string(), expected }),
    }
}

/// Parse the arguments after the program name.
pub fn parse_args<I, S>(args: I) -> Result<Command, ArgError>
where
    I: IntoIterator<Item = S>,
    S: Into<String>,
{
    let mut device = None;
    let mut o = Options::new("");
    let mut it = args.into_iter().map(Into::into);
    while let Some(arg) = it.next() {
        let (name, inline) = match arg.split_once('=') {
            Some((n, v)) if n.starts_with("--") => (n.to_string(), Some(v.to_string())),
            _ => (arg.clone(), None),
        };
        let flag: &'static str = match name.as_str() {
            "-h" | "--help" => return Ok(Command::Help),
            "-V" | "--version" => return Ok(Command::Version),
            "-v" | "--verbose" if inline.is_none() => {
                o.verbose = true;
                continue;
            }
            "-d" | "--device" => "--device",
            "-b" | "--baud" => "--baud",
            "-a" | "--address" => "--address",
            "-c" | "--config" => "--config",
            "-s" | "--state" => "--state",
            "--ramp-ms" => "--ramp-ms",
            "--pd-every" => "--pd-every",
            "--idle-us" => "--idle-us",
            _ => return Err(ArgError::Unknown(arg)),
        };
        let value = match inline.or_else(|| it.next()) {
            Some(v) => v,
            None => return Err(ArgError::MissingValue(flag)),
        };
        match flag {
            "--device" if !value.is_empty() => device = Some(value),
            "--device" => return Err(ArgError::Invalid { flag, value, expected: "a path" }),
            "--baud" => {
                o.baud = parse_baud(&value).ok_or(ArgError::Invalid { flag, value, expected: RATES })?;
            }
            "--address" => {
                let mut list = Vec::new();
                for a in value.split(',') {
                    list.push(
                        parse_u64(flag, a.trim(), card::MAX_STATION_ADDRESS as u64, "0..=126, or a list 5,6,7")? as u8
                    );
                }
                o.address = list[0];
                o.more_addresses = list[1..].to_vec();
            }
            "--config" if !value.is_empty() => o.config = Some(value),
            "--config" => return Err(ArgError::Invalid { flag, value, expected: "a file" }),
            "--state" if !value.is_empty() => o.state = Some(value),
            "--state" => return Err(ArgError::Invalid { flag, value, expected: "a file" }),
            "--ramp-ms" => o.ramp = Duration::from_millis(parse_u64(flag, &value, 3_600_000, "0..=3600000 ms")?),
            "--pd-every" => {
                let s = parse_u64(flag, &value, 86_400, "0..=86400 s")?;
                o.pd_every = (s > 0).then(|| Duration::from_secs(s));
            }
            _ => o.idle = Some(Duration::from_micros(parse_u64(flag, &value, 10_000_000, "0..=10000000 µs")?)),
        }
    }
    o.device = device.ok_or(ArgError::NoDevice)?;
    Ok(Command::Run(o))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn flags() {
        let c = parse_args(["--device", "/dev/ttyUSB0", "-b", "1.5M", "--address=5", "-v", "--pd-every", "0"]).unwrap();
        let Command::Run(o) = c else { panic!() };
        assert_eq!(o.device, "/dev/ttyUSB0");
        assert_eq!(o.baud, Baudrate::B1500k);
        assert_eq!(o.address, 5);
        assert!(o.verbose);
        assert_eq!(o.pd_every, None);
        assert_eq!(o.ramp, Duration::from_millis(2000));
        assert_eq!(o.state, None);
        let Command::Run(o) = parse_args(["-d", "x", "--state", "/tmp/card.state"]).unwrap() else { panic!() };
        assert_eq!(o.state.as_deref(), Some("/tmp/card.state"));
        assert!(matches!(parse_args(["-d", "x", "--state="]), Err(ArgError::Invalid { flag: "--state", .. })));
        assert_eq!(parse_args(["-d", "x", "-s"]), Err(ArgError::MissingValue("--state")));
        assert_eq!(parse_args(["-d", "x", "--help"]), Ok(Command::Help));
        assert_eq!(parse_args(["-V"]), Ok(Command::Version));
        let Command::Run(o) = parse_args(["-d", "pty", "--address", "5,6, 7"]).unwrap() else { panic!() };
        assert_eq!((o.address, o.more_addresses.as_slice()), (5, &[6, 7][..]));
        assert_eq!(o.stations().unwrap().iter().map(|s| s.address).collect::<Vec<_>>(), [5, 6, 7]);
        let Command::Run(o) = parse_args(["-d", "pty", "--address", "5,6,5"]).unwrap() else { panic!() };
        assert_eq!(o.stations().unwrap_err().to_string(), "configuration: station address 5 is given twice");
        assert!(matches!(parse_args(["-d", "x", "-a", "5,,6"]), Err(ArgError::Invalid { flag: "--address", .. })));
    }

    #[test]
    fn errors() {
        assert_eq!(parse_args(Vec::<String>::new()), Err(ArgError::NoDevice));
        assert_eq!(parse_args(["--device"]), Err(ArgError::MissingValue("--device")));
        assert_eq!(parse_args(["--frob"]), Err(ArgError::Unknown("--frob".into())));
        assert!(matches!(parse_args(["-d", "x", "-a", "127"]), Err(ArgError::Invalid { flag: "--address", .. })));
        assert!(matches!(parse_args(["-d", "x", "-b", "115200"]), Err(ArgError::Invalid { flag: "--baud", .. })));
        assert_eq!(parse_args(["--verbose=1"]), Err(ArgError::Unknown("--verbose=1".into())));
    }

    #[test]
    fn rates_in_every_spelling() {
        let cases = [
            ("9600", Baudrate::B9600),
            ("19.2k", Baudrate::B19200),
            ("45.45k", Baudrate::B45450),
            ("93.75k", Baudrate::B93750),
            ("187.5K", Baudrate::B187500),
            ("500k", Baudrate::B500k),
            ("1.5M", Baudrate::B1500k),
            ("1500k", Baudrate::B1500k),
            ("12M", Baudrate::B12M),
        ];
        for (s, r) in cases {
            assert_eq!(parse_baud(s), Some(r), "{s}");
        }
        for s in ["", "k", ".5k", "1.", "19.20001k", "-9600", "0x10", "12MM", "9600 k", "1.5m"] {
            assert_eq!(parse_baud(s), None, "{s}");
        }
    }

    proptest! {
        #[test]
        fn any_arguments_parse_or_fail_cleanly(args in proptest::collection::vec(".{0,12}", 0..6)) {
            let _ = parse_args(args);
        }

        #[test]
        fn any_rate_text(s in "[0-9.kKM]{0,14}") {
            if let Some(r) = parse_baud(&s) {
                prop_assert_eq!(parse_baud(&r.bits_per_second().to_string()), Some(r));
            }
        }

        #[test]
        fn every_rate_round_trips(i in 0usize..10, k in proptest::bool::ANY) {
            let r = Baudrate::ALL[i];
            let bps = r.bits_per_second();
            let text = if k { format!("{}k", bps as f64 / 1000.0) } else { bps.to_string() };
            prop_assert_eq!(parse_baud(&text), Some(r));
        }

        #[test]
        fn addresses(a in 0u16..300) {
            let r = parse_args(["-d".to_string(), "x".to_string(), "-a".to_string(), a.to_string()]);
            prop_assert_eq!(r.is_ok(), a <= 126);
        }
    }
}
