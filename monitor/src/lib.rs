//! # pbcard-monitor — a listen-only PROFIBUS bus monitor
//!
//! Decodes what it hears with the pbcard project's own parsers: FDL frames
//! ([`pbcard::fdl::telegram`]), the DP services ([`pbcard::dp`]: Set_Prm, Chk_Cfg/Get_Cfg,
//! Slave_Diag, Global_Control, Set_Slave_Add), DP-V1 ([`pbcard::dpv1::pdu`]; the records of
//! DS_Write / DS_Read and of MSAC_C2 Data_Transport through one decoder, I&M0–I&M4 in [`im`]
//! with the I&M call tracked per relation) and PROFIdrive (record-47 parameter access
//! [`pbcard::profile::param`], PKW, STW1/ZSW1 of a telegram known from the Chk_Cfg). Per
//! station it matches every request with its response, measures the response time against the
//! GSD's MaxTsdr for the rate, counts retries and missing answers and the Data_Exchange cycle
//! time.
//!
//! The pipeline: bytes (+ times) → [`cut::Cutter`] (telegrams cut by syntax, garbage shown as
//! such) → [`Monitor::on_cut`] → [`Line`]s (text with [`Line::text_line`], JSON with
//! [`Line::json`]) and [`Monitor::summary`].
//!
//! Times: the monitor knows when a chunk of bytes was read, not each byte (USB adapters deliver
//! chunks), so a response time is "end of the response − end of the request − the response's own
//! transmission time". From a capture with exact times (tests, a logic analyser) that is exact;
//! from a USB adapter it is as good as the adapter's read latency.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod capture;
pub mod cut;
pub mod decode;
pub mod im;
pub mod product;

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::Serialize;

use pbcard::dp::sap;
use pbcard::dpv1::pdu;
use pbcard::fdl::telegram::{self, DataFormat, Decoded, RequestFunction, Telegram};
use pbcard::time::{Baudrate, Duration};

use cut::{Cut, Why};
use product::Product;

pub use pbcard_softslave::hex;

/// The SAP of MSAC_C1 (DP-V1 class 1 read / write, reference §4.1).
pub const SAP_C1: u8 = 51;
/// The SAP of MSAC_C1 Alarm_Ack.
pub const SAP_C1_ALARM: u8 = 50;
/// The SAP of the MSAC_C2 resource manager (Initiate).
pub const SAP_C2_RM: u8 = 49;

/// One output line: a telegram, garbage, or a request that got no answer.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Line {
    /// `telegram`, `garbage` or `no_response`.
    pub kind: &'static str,
    /// Seconds since the start, when known.
    pub t: Option<f64>,
    /// `SD1` `SD2` `SD3` `SD4` `SC`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sd: Option<&'static str>,
    /// Destination address.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub da: Option<u8>,
    /// Source address.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sa: Option<u8>,
    /// Function code by name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fc: Option<String>,
    /// The service (issue 14's list: `Set_Prm`, `Data_Exchange`, `Response`, `Unknown` …).
    pub service: &'static str,
    /// For a response: the service of the request it answers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub request: Option<&'static str>,
    /// Destination SAP.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dsap: Option<u8>,
    /// Source SAP.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ssap: Option<u8>,
    /// DP-V1 slot.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slot: Option<u8>,
    /// DP-V1 index.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub index: Option<u8>,
    /// PROFIdrive PNU (the first of a request).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pnu: Option<u16>,
    /// An error the telegram carries or is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// The request repeats an unanswered one.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub retry: bool,
    /// A DP-V1 poll (request without data fetching the response).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub poll: bool,
    /// Response time in bit times (responses, when times are known).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tsdr_bits: Option<u64>,
    /// The response came later than MaxTsdr.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub late: bool,
    /// The decoded content.
    pub text: String,
    /// The bytes.
    pub hex: String,
}

impl Line {
    /// The readable line: `    0.012345   2→5   SD2 SRD_high FCB=1 FCV=1 62→61  Set_Prm  …`.
    pub fn text_line(&self) -> String {
        let t = self.t.map_or_else(|| "           -".to_string(), |t| format!("{t:12.6}"));
        let dir = match (self.sa, self.da) {
            (Some(s), Some(d)) => format!("{s:>3}→{d:<3}"),
            _ => "       ".into(),
        };
        let mut frame = String::new();
        if let Some(sd) = self.sd {
            frame.push_str(sd);
        }
        if let Some(fc) = self.fc.as_deref().filter(|fc| Some(*fc) != self.sd) {
            let _ = write!(frame, " {fc}");
        }
        match (self.ssap, self.dsap) {
            (Some(s), Some(d)) => {
                let _ = write!(frame, " {s}→{d}");
            }
            (None, Some(d)) => {
                let _ = write!(frame, " →{d}");
            }
            (Some(s), None) => {
                let _ = write!(frame, " {s}→");
            }
            _ => {}
        }
        let service = match (self.kind, self.request) {
            ("no_response", _) => format!("NO ANSWER to {}", self.service),
            (_, Some(r)) => format!("Response({r})"),
            _ => self.service.to_string(),
        };
        let mut notes = String::new();
        if self.retry {
            notes.push_str(" [retry]");
        }
        if self.poll {
            notes.push_str(" [poll]");
        }
        if let Some(b) = self.tsdr_bits {
            let _ = write!(notes, " [TSDR {b} bit{}]", if self.late { " LATE" } else { "" });
        }
        format!("{t} {dir} {frame:<28} {service:<22} {}{notes}", self.text)
    }

    /// One JSON object.
    pub fn json(&self) -> String {
        serde_json::to_string(self).unwrap_or_else(|e| format!("{{\"kind\":\"error\",\"text\":\"{e}\"}}"))
    }
}

/// Min / sum / max of a series.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Series {
    /// Samples.
    pub n: u64,
    /// Smallest.
    pub min: u64,
    /// Largest.
    pub max: u64,
    /// Sum.
    pub sum: u64,
}

impl Series {
    fn add(&mut self, v: u64) {
        if self.n == 0 || v < self.min {
            self.min = v;
        }
        self.max = self.max.max(v);
        self.sum = self.sum.saturating_add(v);
        self.n += 1;
    }
    /// The mean, when there are samples.
    pub fn mean(&self) -> Option<f64> {
        (self.n > 0).then(|| self.sum as f64 / self.n as f64)
    }
}

/// What the monitor counted for one station (as a responder).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct StationStats {
    /// Requests addressed to it that want an answer.
    pub requests: u64,
    /// Answers matched to them.
    pub answered: u64,
    /// Requests without an answer.
    pub missing: u64,
    /// Requests repeating an unanswered one.
    pub retries: u64,
    /// Data_Exchange requests.
    pub data_exchanges: u64,
    /// Time between Data_Exchange requests, µs.
    pub cycle_us: Series,
    /// Response times, bit times.
    pub tsdr_bits: Series,
    /// Responses later than MaxTsdr.
    pub late: u64,
    /// DP-V1 negative responses and PROFIdrive error values.
    pub errors: u64,
    /// What the monitor believes the station's DP state is.
    pub state: &'static str,
    /// The module from the last acknowledged Chk_Cfg.
    pub module: Option<String>,
    /// Masters that addressed it.
    pub masters: Vec<u8>,
}

/// A DP-V1 request waiting for its response (per station, master and SAP).
#[derive(Debug, Clone, Default)]
struct Job {
    service: &'static str,
    slot: Option<u8>,
    index: Option<u8>,
    pnus: Vec<u16>,
    /// Index 255: the FI_Index of the I&M call a write / Data_Transport carries, or for a
    /// read the one the relation's last call selected.
    im: Option<u16>,
}

#[derive(Debug, Default)]
struct Station {
    stats: StationStats,
    /// Chk_Cfg bytes waiting for the acknowledgement.
    cfg_sent: Option<Vec<u8>>,
    telegram: Option<pbcard::dpm::Telegram>,
    dpv1: bool,
    jobs: BTreeMap<(u8, u8), Job>,
    /// Last request bytes from each master and whether it was answered.
    last: BTreeMap<u8, (Vec<u8>, bool)>,
    last_dx_us: Option<u64>,
    /// Set_Prm bytes waiting for the acknowledgement.
    prm_sent: Option<bool>,
    /// The FI_Index the last accepted I&M call selected, per relation (master, the station's
    /// SAP: 51 = MSAC_C1, a server SAP = that MSAC_C2 connection; reference §4.7).
    im_calls: BTreeMap<(u8, u8), u16>,
}

/// The request on the line waiting for its answer.
#[derive(Debug, Clone)]
struct Outstanding {
    t_us: Option<u64>,
    sa: u8,
    da: u8,
    service: &'static str,
    dsap: Option<u8>,
    job: Option<Job>,
}

/// The decoder and per-station bookkeeping.
#[derive(Debug)]
pub struct Monitor {
    product: Product,
    rate: Option<Baudrate>,
    stations: BTreeMap<u8, Station>,
    outstanding: Option<Outstanding>,
    t0: Option<u64>,
    /// Garbage runs seen.
    pub garbage: u64,
    /// Telegrams seen.
    pub telegrams: u64,
}

fn sd_name(b: &[u8]) -> Option<&'static str> {
    Some(match *b.first()? {
        telegram::SD1 => "SD1",
        telegram::SD2 => "SD2",
        telegram::SD3 => "SD3",
        telegram::SD4 => "SD4",
        telegram::SC => "SC",
        _ => return None,
    })
}

fn secs(t_us: Option<u64>) -> Option<f64> {
    t_us.map(|t| t as f64 / 1e6)
}

impl Monitor {
    /// A monitor naming things by `product`, timing at `rate` (None: no timing judgement).
    pub fn new(product: Product, rate: Option<Baudrate>) -> Self {
        Monitor { product, rate, stations: BTreeMap::new(), outstanding: None, t0: None, garbage: 0, telegrams: 0 }
    }

    /// The rate changed (a capture's `rate` line).
    pub fn set_rate(&mut self, rate: Baudrate) {
        self.rate = Some(rate);
    }

    /// The rate the times are judged at.
    pub fn rate(&self) -> Option<Baudrate> {
        self.rate
    }

    /// Per-station counters.
    pub fn stations(&self) -> BTreeMap<u8, StationStats> {
        self.stations.iter().map(|(a, s)| (*a, s.stats.clone())).collect()
    }

    fn station(&mut self, a: u8) -> &mut Station {
        self.stations.entry(a).or_insert_with(|| Station {
            stats: StationStats { state: "seen", ..Default::default() },
            ..Default::default()
        })
    }

    /// Decode one cut of the input.
    pub fn on_cut(&mut self, cut: &Cut) -> Vec<Line> {
        let mut out = Vec::new();
        match cut {
            Cut::Garbage { bytes, t_us, why } => {
                self.garbage += 1;
                let why = match why {
                    Why::NoStartDelimiter => "no start delimiter".to_string(),
                    Why::Invalid(e) => format!("invalid telegram: {e:?}"),
                    Why::Truncated => "truncated telegram".to_string(),
                    Why::LineError => "character error (parity / framing)".to_string(),
                };
                out.push(Line {
                    kind: "garbage",
                    t: self.rel(*t_us),
                    service: "Unknown",
                    error: Some(why.clone()),
                    text: format!("{} bytes: {why}", bytes.len()),
                    hex: hex(bytes),
                    ..Default::default()
                });
            }
            Cut::Frame { bytes, t_us } => {
                self.telegrams += 1;
                self.on_frame(bytes, *t_us, &mut out);
            }
        }
        out
    }

    /// The end of the input: a request still waiting is unanswered.
    pub fn finish(&mut self) -> Vec<Line> {
        let mut out = Vec::new();
        self.unanswered(&mut out);
        out
    }

    fn rel(&mut self, t_us: Option<u64>) -> Option<f64> {
        let t = t_us?;
        let t0 = *self.t0.get_or_insert(t);
        secs(Some(t.saturating_sub(t0)))
    }

    fn unanswered(&mut self, out: &mut Vec<Line>) {
        if let Some(o) = self.outstanding.take() {
            let st = self.station(o.da);
            st.stats.missing += 1;
            if let Some(l) = st.last.get_mut(&o.sa) {
                l.1 = false;
            }
            let t = self.rel(o.t_us);
            out.push(Line {
                kind: "no_response",
                t,
                da: Some(o.da),
                sa: Some(o.sa),
                service: o.service,
                dsap: o.dsap,
                text: format!("station {} did not answer", o.da),
                ..Default::default()
            });
        }
    }

    fn on_frame(&mut self, bytes: &[u8], t_us: Option<u64>, out: &mut Vec<Line>) {
        let mut line = Line { kind: "telegram", sd: sd_name(bytes), hex: hex(bytes), ..Default::default() };
        match telegram::decode(bytes) {
            Decoded::Frame(Telegram::ShortAck, _) => {
                line.fc = Some("SC".into());
                line.service = "Response";
                self.response(&mut line, None, t_us, bytes.len(), out);
            }
            Decoded::Frame(Telegram::Token { da, sa }, _) => {
                self.unanswered(out);
                line.t = self.rel(t_us);
                line.service = "Token";
                line.da = Some(da);
                line.sa = Some(sa);
                line.text = format!("token from {sa} to {da}");
                out.push(line);
            }
            Decoded::Frame(Telegram::Data(d), _) => {
                line.da = Some(d.da);
                line.sa = Some(d.sa);
                line.dsap = d.dsap;
                line.ssap = d.ssap;
                line.fc = Some(decode::fc_name(d.fc));
                if d.format == DataFormat::Sd3 {
                    line.fc = line.fc.map(|f| format!("{f} (SD3)"));
                }
                if d.fc.is_request() {
                    self.unanswered(out);
                    line.t = self.rel(t_us);
                    self.request(&mut line, &d, t_us, bytes);
                    out.push(line);
                } else {
                    line.service = "Response";
                    self.response(&mut line, Some(&d), t_us, bytes.len(), out);
                }
            }
            // The cutter hands out valid telegrams only; a caller feeding other bytes gets them
            // shown as such.
            Decoded::Incomplete | Decoded::Invalid(_) => {
                line.kind = "garbage";
                line.t = self.rel(t_us);
                line.service = "Unknown";
                line.error = Some("not a telegram".into());
                line.text = "not a telegram".into();
                out.push(line);
            }
        }
    }

    fn request(&mut self, line: &mut Line, d: &telegram::DataTelegram<'_>, t_us: Option<u64>, bytes: &[u8]) {
        let function = d.fc.function();
        let wants_answer = d.da != telegram::BROADCAST
            && !matches!(function, RequestFunction::SdnLow | RequestFunction::SdnHigh | RequestFunction::TimeEvent);
        let product = self.product.clone();
        let (service, text, job) = self.classify(d, &product);
        line.service = service;
        line.text = text;
        if let Some(j) = &job {
            line.slot = j.slot;
            line.index = j.index;
            line.pnu = j.pnus.first().copied();
            line.poll = d.pdu.is_empty();
        }
        if d.da == telegram::BROADCAST {
            return;
        }
        let st = self.station(d.da);
        if !st.stats.masters.contains(&d.sa) {
            st.stats.masters.push(d.sa);
        }
        if service == "Data_Exchange" {
            st.stats.data_exchanges += 1;
            if let (Some(t), Some(last)) = (t_us, st.last_dx_us) {
                st.stats.cycle_us.add(t.saturating_sub(last));
            }
            st.last_dx_us = t_us.or(st.last_dx_us);
        }
        if wants_answer {
            st.stats.requests += 1;
            if let Some((prev, answered)) = st.last.get(&d.sa) {
                if !answered && prev.as_slice() == bytes {
                    line.retry = true;
                    st.stats.retries += 1;
                }
            }
            st.last.insert(d.sa, (bytes.to_vec(), false));
            self.outstanding = Some(Outstanding { t_us, sa: d.sa, da: d.da, service, dsap: d.dsap, job });
        }
    }

    /// Service, text and (DP-V1) job of a request.
    fn classify(&mut self, d: &telegram::DataTelegram<'_>, product: &Product) -> (&'static str, String, Option<Job>) {
        if d.fc.function() == RequestFunction::FdlStatus {
            return ("FDL_Status", "request FDL status".into(), None);
        }
        if !matches!(
            d.fc.function(),
            RequestFunction::SrdLow
                | RequestFunction::SrdHigh
                | RequestFunction::SdnLow
                | RequestFunction::SdnHigh
                | RequestFunction::SdaLow
                | RequestFunction::SdaHigh
        ) {
            return ("Unknown", format!("FDL function {} not used by DP: {}", decode::fc_name(d.fc), hex(d.pdu)), None);
        }
        let da = d.da;
        match d.dsap {
            None => {
                let text = match self.stations.get(&da).and_then(|s| s.telegram) {
                    Some(t) if !d.pdu.is_empty() => format!("outputs {}", decode::process_data(d.pdu, t, true)),
                    _ if d.pdu.is_empty() => "no outputs (fail-safe / Clear)".into(),
                    _ => format!("outputs {}", hex(d.pdu)),
                };
                ("Data_Exchange", text, None)
            }
            Some(sap::SET_PRM) => {
                let dpv1 = d.pdu.get(7).is_some_and(|b| b & 0x80 != 0);
                let st = self.station(da);
                st.prm_sent = Some(dpv1);
                // MSAC_C1 ends when the station leaves data exchange: its I&M calls are gone.
                st.im_calls.retain(|&(_, sap), _| sap != SAP_C1);
                ("Set_Prm", decode::set_prm(d.pdu, product), None)
            }
            Some(sap::CHK_CFG) => {
                self.station(da).cfg_sent = Some(d.pdu.to_vec());
                ("Chk_Cfg", decode::cfg_data(d.pdu, product), None)
            }
            Some(sap::GET_CFG) => ("Get_Cfg", "read the configuration".into(), None),
            Some(sap::SLAVE_DIAG) => ("Slave_Diag", "read the diagnosis".into(), None),
            Some(sap::GLOBAL_CONTROL) => ("Global_Control", decode::global_control(d.pdu), None),
            Some(sap::SET_SLAVE_ADD) => ("Set_Slave_Add", decode::set_slave_add(d.pdu, product), None),
            Some(sap::RD_INP) => ("Rd_Inp", "read the inputs".into(), None),
            Some(sap::RD_OUTP) => ("Rd_Outp", "read the outputs".into(), None),
            Some(s) if s <= SAP_C1 => self.dpv1_request(d, s),
            Some(s) => ("Unknown", format!("SAP {s}: {}", hex(d.pdu)), None),
        }
    }

    fn dpv1_request(&mut self, d: &telegram::DataTelegram<'_>, s: u8) -> (&'static str, String, Option<Job>) {
        let class = match s {
            SAP_C1 => "MSAC_C1",
            SAP_C1_ALARM => "MSAC_C1 alarm",
            SAP_C2_RM => "MSAC_C2 resource manager",
            _ => "MSAC_C2",
        };
        let key = (d.sa, s);
        if d.pdu.is_empty() {
            let job = self.stations.get(&d.da).and_then(|st| st.jobs.get(&key)).cloned();
            return match job {
                Some(j) => (j.service, format!("{class} poll for the {} response", j.service), Some(j)),
                None => ("Unknown", format!("{class} poll, no request seen"), Some(Job::default())),
            };
        }
        match pdu::parse(d.pdu) {
            Ok(r) => {
                let service = decode::dpv1_service(r.function());
                let mut job = Job { service, ..Default::default() };
                let st = self.station(d.da);
                match &r {
                    pdu::Request::Read(x) => {
                        (job.slot, job.index) = (Some(x.slot), Some(x.index));
                        if x.index == im::INDEX {
                            job.im = st.im_calls.get(&key).copied();
                        }
                    }
                    pdu::Request::Write(x) | pdu::Request::DataTransport(x) => {
                        (job.slot, job.index) = (Some(x.slot), Some(x.index));
                        if x.index == pbcard::profile::param::RECORD_INDEX {
                            job.pnus = decode::param_request(x.data).1;
                        } else if x.index == im::INDEX {
                            job.im = im::call_index(x.data);
                        }
                    }
                    pdu::Request::AlarmAck(a) => job.slot = Some(a.slot),
                    // A connection opened or closed on this SAP: a new relation.
                    pdu::Request::Initiate(_) | pdu::Request::Abort(_) => {
                        st.im_calls.remove(&key);
                    }
                    _ => {}
                }
                // A read of record 47 fetches the response to the last record-47 write.
                if let (pdu::Request::Read(x), Some(w)) = (&r, st.jobs.get(&(d.sa, 255 - s))) {
                    if x.index == pbcard::profile::param::RECORD_INDEX {
                        job.pnus = w.pnus.clone();
                    }
                }
                if let pdu::Request::Write(x) = &r {
                    if x.index == pbcard::profile::param::RECORD_INDEX {
                        st.jobs.insert((d.sa, 255 - s), job.clone());
                    }
                }
                st.jobs.insert(key, job.clone());
                (service, format!("{class} {}", decode::dpv1_request(&r)), Some(job))
            }
            Err(e) => {
                ("Unknown", format!("{class}: not a DP-V1 request ({e:?}): {}", hex(d.pdu)), Some(Job::default()))
            }
        }
    }

    fn response(
        &mut self,
        line: &mut Line,
        d: Option<&telegram::DataTelegram<'_>>,
        t_us: Option<u64>,
        len: usize,
        out: &mut Vec<Line>,
    ) {
        line.t = self.rel(t_us);
        let matches = match (&self.outstanding, d) {
            (Some(_), None) => true,
            (Some(o), Some(d)) => d.da == o.sa && d.sa == o.da,
            (None, _) => false,
        };
        if !matches {
            self.unanswered(out);
            line.request = None;
            if d.is_none() {
                line.service = "SC";
            }
            line.text = match d {
                Some(d) => format!("response without a request: {}", hex(d.pdu)),
                None => "SC without a request".into(),
            };
            out.push(line.clone());
            return;
        }
        let Some(o) = self.outstanding.take() else { return };
        line.request = Some(o.service);
        if let Some(d) = d {
            line.dsap = d.dsap;
            line.ssap = d.ssap;
        }
        // Response time: end of the response − its transmission − end of the request.
        if let (Some(rate), Some(t1), Some(t0)) = (self.rate, t_us, o.t_us) {
            let tx = rate.bits_to_duration(11 * len as u32).as_micros();
            let us = t1.saturating_sub(t0).saturating_sub(tx);
            let bits = rate.duration_to_bits(Duration::from_micros(us));
            line.tsdr_bits = Some(bits);
            line.late = bits > u64::from(self.product.max_tsdr(rate));
        }
        let product = self.product.clone();
        let st = self.station(o.da);
        st.stats.answered += 1;
        if let Some(l) = st.last.get_mut(&o.sa) {
            l.1 = true;
        }
        if let Some(b) = line.tsdr_bits {
            st.stats.tsdr_bits.add(b);
            if line.late {
                st.stats.late += 1;
            }
        }
        if let Some(j) = &o.job {
            line.slot = j.slot;
            line.index = j.index;
            line.pnu = j.pnus.first().copied();
        }
        let pdu = d.map_or(&[][..], |d| d.pdu);
        let meaning = d.and_then(|d| decode::response_meaning(d.fc));
        let sc = d.is_none();
        line.text = match o.service {
            "FDL_Status" => match d {
                Some(d) => format!("station type: {}", decode::station_type(d.fc)),
                None => "SC".into(),
            },
            "Set_Prm" | "Chk_Cfg" | "Set_Slave_Add" | "Global_Control" if sc => {
                match o.service {
                    "Set_Prm" => {
                        st.dpv1 = st.prm_sent.take().unwrap_or(false);
                        st.stats.state = "Wait_Cfg";
                    }
                    "Chk_Cfg" => {
                        if let Some(c) = st.cfg_sent.take() {
                            st.stats.module =
                                Some(product.module(&c).map_or_else(|| format!("cfg {}", hex(&c)), |m| m.name.clone()));
                            st.telegram = pbcard::card::module_for_cfg(&c).and_then(pbcard::dpm::Telegram::of_module);
                        }
                    }
                    _ => {}
                }
                "acknowledged (SC); the next Slave_Diag tells whether it was accepted".into()
            }
            "Slave_Diag" if !pdu.is_empty() => {
                if let Some(&s1) = pdu.first() {
                    let s2 = pdu.get(1).copied().unwrap_or(0);
                    st.stats.state = if s2 & 0x01 != 0 || s1 & 0x40 != 0 {
                        "Wait_Prm"
                    } else if s1 & 0x06 != 0 {
                        if s1 & 0x04 != 0 {
                            "Cfg_Fault"
                        } else {
                            st.stats.state
                        }
                    } else {
                        "ready"
                    };
                    if s1 & 0x04 != 0 {
                        st.telegram = None;
                    }
                }
                decode::slave_diag(pdu, &product, st.dpv1)
            }
            "Get_Cfg" if !pdu.is_empty() => decode::cfg_data(pdu, &product),
            "Data_Exchange" => {
                if !sc && (d.is_some_and(|d| d.fc.0 & 0x0F == 0x8 || d.fc.0 & 0x0F == 0xA)) {
                    st.stats.state = "Data_Exch";
                }
                let mut s = match (st.telegram, pdu.is_empty()) {
                    (_, true) => "no inputs".to_string(),
                    (Some(t), false) => format!("inputs {}", decode::process_data(pdu, t, false)),
                    (None, false) => format!("inputs {}", hex(pdu)),
                };
                if let Some(m) = meaning {
                    let _ = write!(s, " — {m}");
                }
                s
            }
            "Rd_Inp" | "Rd_Outp" if !pdu.is_empty() => format!("data {}", hex(pdu)),
            "DS_Read" | "DS_Write" | "Alarm_Ack" | "Initiate" | "Abort" | "Data_Transport" | "Idle"
                if !pdu.is_empty() =>
            {
                match pdu::Response::parse(pdu) {
                    Ok(r) => {
                        let job = o.job.as_ref();
                        let pnus = job.map_or(&[][..], |j| j.pnus.as_slice());
                        let (t, err) = decode::dpv1_response(&r, pnus, job.and_then(|j| j.im));
                        if let (Some(j), Some(dsap)) = (job, o.dsap) {
                            match r {
                                // A call the station accepted selects the record on this relation.
                                pdu::Response::Write { index: im::INDEX, .. }
                                | pdu::Response::DataTransport(pdu::DataRequest { index: im::INDEX, .. }) => {
                                    if let Some(fi) = j.im {
                                        st.im_calls.insert((o.sa, dsap), fi);
                                    }
                                }
                                pdu::Response::Abort(_) => {
                                    st.im_calls.remove(&(o.sa, dsap));
                                }
                                _ => {}
                            }
                        }
                        if let Some(e) = err {
                            line.error = Some(e);
                            st.stats.errors += 1;
                        }
                        if let Some(dsap) = o.dsap {
                            st.jobs.remove(&(o.sa, dsap));
                        }
                        t
                    }
                    Err(e) => {
                        line.error = Some(format!("{e:?}"));
                        format!("not a DP-V1 response ({e:?}): {}", hex(pdu))
                    }
                }
            }
            _ if sc => match o.service {
                "DS_Read" | "DS_Write" | "Alarm_Ack" | "Initiate" | "Abort" | "Data_Transport" | "Idle" => {
                    "SC: request accepted / response not ready yet".into()
                }
                _ => "SC".into(),
            },
            _ => {
                let mut s = if pdu.is_empty() { "no data".to_string() } else { format!("data {}", hex(pdu)) };
                if let Some(m) = meaning {
                    let _ = write!(s, " — {m}");
                }
                s
            }
        };
        if let Some(d) = d {
            if matches!(d.fc.0 & 0x0F, 0x1..=0x3) {
                line.error = Some(decode::response_meaning(d.fc).unwrap_or("").to_string());
                st.stats.errors += 1;
            }
        }
        out.push(line.clone());
    }

    /// The per-station summary table.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let rate = self.rate.map_or("rate unknown".to_string(), |r| format!("{} bit/s", r.bits_per_second()));
        let _ = writeln!(
            s,
            "summary: {} telegrams, {} garbage runs, {rate}, names from {}",
            self.telegrams, self.garbage, self.product.source
        );
        let _ = writeln!(
            s,
            "{:>4} {:<10} {:<32} {:>6} {:>6} {:>5} {:>5} {:>7} {:>23} {:>16} {:>5} {:>5}",
            "stn",
            "state",
            "module",
            "req",
            "ans",
            "miss",
            "retry",
            "DX",
            "cycle ms min/avg/max",
            "TSDR bit min/max",
            "late",
            "err"
        );
        for (a, st) in &self.stations {
            let x = &st.stats;
            let cycle = match x.cycle_us.mean() {
                Some(m) => format!(
                    "{:.2}/{:.2}/{:.2}",
                    x.cycle_us.min as f64 / 1000.0,
                    m / 1000.0,
                    x.cycle_us.max as f64 / 1000.0
                ),
                None => "-".into(),
            };
            let tsdr = match (x.tsdr_bits.n, self.rate) {
                (0, _) => "-".into(),
                (_, Some(r)) => format!("{}/{} (max {})", x.tsdr_bits.min, x.tsdr_bits.max, self.product.max_tsdr(r)),
                (_, None) => format!("{}/{}", x.tsdr_bits.min, x.tsdr_bits.max),
            };
            let state = if x.answered == 0 && x.requests > 0 { "absent" } else { x.state };
            let module: String = x.module.clone().unwrap_or_else(|| "-".into()).chars().take(32).collect();
            let _ = writeln!(
                s,
                "{a:>4} {state:<10} {module:<32} {:>6} {:>6} {:>5} {:>5} {:>7} {cycle:>23} {tsdr:>16} {:>5} {:>5}",
                x.requests, x.answered, x.missing, x.retries, x.data_exchanges, x.late, x.errors
            );
        }
        s
    }
}

/// Decode a whole byte stream without times (raw input): every line, then the end.
pub fn decode_raw(product: Product, rate: Option<Baudrate>, bytes: &[u8]) -> (Vec<Line>, Monitor) {
    let mut m = Monitor::new(product, rate);
    let mut c = cut::Cutter::new();
    let mut cuts = Vec::new();
    c.push(None, bytes, &mut cuts);
    c.finish(&mut cuts);
    let mut lines: Vec<Line> = cuts.iter().flat_map(|x| m.on_cut(x)).collect();
    lines.extend(m.finish());
    (lines, m)
}

/// Replay a capture (the text of a capture file): every line; a record that is not one is
/// shown as a garbage line with the reason and the replay goes on.
pub fn replay(product: Product, text: &str, gap_us: Option<u64>) -> (Vec<Line>, Monitor) {
    let mut m = Monitor::new(product, None);
    let mut c = cut::Cutter::new();
    let mut lines = Vec::new();
    let mut last_t: Option<u64> = None;
    for (no, l) in text.lines().enumerate() {
        let mut cuts = Vec::new();
        match capture::parse_line(l) {
            Ok(capture::Record::Comment) => {}
            Ok(capture::Record::Rate(r)) => m.set_rate(r),
            Ok(capture::Record::Bytes { t_us, bytes }) => {
                if let (Some(g), Some(t), Some(last)) = (gap_us, t_us, last_t) {
                    if t.saturating_sub(last) > g && c.pending() > 0 {
                        c.gap(&mut cuts);
                    }
                }
                last_t = t_us.or(last_t);
                c.push(t_us, &bytes, &mut cuts);
            }
            Ok(capture::Record::LineError { t_us }) => c.line_error(t_us, &mut cuts),
            Err(e) => lines.push(Line {
                kind: "garbage",
                service: "Unknown",
                error: Some(format!("capture line {}: {e}", no + 1)),
                text: format!("capture line {} unreadable: {e}", no + 1),
                ..Default::default()
            }),
        }
        for x in &cuts {
            lines.extend(m.on_cut(x));
        }
    }
    let mut cuts = Vec::new();
    c.finish(&mut cuts);
    for x in &cuts {
        lines.extend(m.on_cut(x));
    }
    lines.extend(m.finish());
    (lines, m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// What the `monitor_decode` fuzz target checks: arbitrary bytes in arbitrary chunks
        /// never panic the decoder, and the cutter accounts for every byte.
        #[test]
        fn any_bytes_decode_and_no_byte_is_lost(
            bytes in proptest::collection::vec(any::<u8>(), 0..600),
            step in 1usize..20,
            gaps in any::<bool>(),
        ) {
            let mut c = cut::Cutter::new();
            let mut m = Monitor::new(Product::card(), Some(Baudrate::B19200));
            let mut cuts = Vec::new();
            for (i, ch) in bytes.chunks(step).enumerate() {
                if gaps && i % 3 == 2 {
                    c.gap(&mut cuts);
                }
                c.push(Some(i as u64 * 100), ch, &mut cuts);
            }
            c.finish(&mut cuts);
            let total: usize = cuts.iter().map(|x| match x {
                Cut::Frame { bytes, .. } | Cut::Garbage { bytes, .. } => bytes.len(),
            }).sum();
            prop_assert_eq!(total, bytes.len());
            for x in &cuts {
                for l in m.on_cut(x) {
                    let _ = l.text_line();
                    let _ = l.json();
                }
            }
            let _ = m.finish();
            let _ = m.summary();
        }

        /// Valid telegrams built from arbitrary fields, with noise between them, are all found.
        #[test]
        fn telegrams_between_noise_are_all_found(
            pdus in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..40), 1..8),
            noise in proptest::collection::vec(0u8..0x10, 0..5),
        ) {
            let mut bytes = Vec::new();
            let mut frames = Vec::new();
            for (i, p) in pdus.iter().enumerate() {
                bytes.extend_from_slice(&noise);
                let hdr = telegram::Header {
                    da: 5, sa: 2, fc: telegram::FunctionCode::request(0xD, i % 2 == 0, true),
                    dsap: (i % 3 == 0).then_some(51), ssap: (i % 3 == 0).then_some(51),
                };
                let mut out = [0u8; telegram::MAX_FRAME_LEN];
                let n = telegram::emit(&mut out, &hdr, p).unwrap();
                bytes.extend_from_slice(&out[..n]);
                frames.push(out[..n].to_vec());
            }
            let (lines, _) = decode_raw(Product::card(), None, &bytes);
            let found: Vec<String> = lines.iter().filter(|l| l.kind == "telegram").map(|l| l.hex.clone()).collect();
            let want: Vec<String> = frames.iter().map(|f| hex(f)).collect();
            prop_assert_eq!(found, want);
        }
    }
}
