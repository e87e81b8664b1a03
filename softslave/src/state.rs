//! `--state FILE`: the station address (Set_Slave_Add, with No_Add_Chg) and I&M1–4 kept
//! across restarts of the soft slave, in the same journal as on the card's flash
//! ([`pbcard::store::Journal`]) over a file-backed flash model ([`FileFlash`]).
//!
//! The file is an image of the two journal sectors: 2 × [`SECTOR_SIZE`] = 32 768 bytes, 0xFF
//! where erased (the card's slot layout, `pbcard::store`). A missing or empty file is
//! created blank; a file of another size is refused (nothing is overwritten; the soft slave
//! stops with the error before it opens the device).
//! Every erase and program is written through to the file and synced, so a killed soft slave
//! keeps the previous or the new value, as the card does after a power cut.
//!
//! With several stations (`--address 5,6,7`, `--config`) each station has its own file,
//! `FILE.<address>` (the address the station is configured with). A stored address replaces
//! the configured one at start; two stations that would end up on one address are refused
//! (the soft slave stops with that error before it opens the device).

use std::fs::{File, OpenOptions};
use std::io;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use pbcard::card::Module;
use pbcard::dp::DpSlave;
use pbcard::dpv1::im::ImData;
use pbcard::node::Node;
use pbcard::store::{Flash, Journal, StationAddress, StoreError};

/// Bytes per journal sector in the file (as the F411's 16 KiB sectors: 64 slots each).
pub const SECTOR_SIZE: u32 = 16 * 1024;
const FILE_LEN: u64 = 2 * SECTOR_SIZE as u64;

/// Two flash sectors in a file: NOR semantics (erase → 0xFF, program only clears bits),
/// written through and synced on every operation.
#[derive(Debug)]
pub struct FileFlash {
    file: File,
    mem: Vec<u8>,
}

impl FileFlash {
    /// Open `path`, creating a blank image when it is missing or empty.
    pub fn open(path: &Path) -> io::Result<FileFlash> {
        let mut file = OpenOptions::new().read(true).write(true).create(true).truncate(false).open(path)?;
        let len = file.metadata()?.len();
        let mut mem = vec![0xFF; FILE_LEN as usize];
        if len == 0 {
            file.write_all_at(&mem, 0)?;
            file.sync_all()?;
        } else if len != FILE_LEN {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("{}: {len} bytes, not a soft-slave state file ({FILE_LEN} bytes)", path.display()),
            ));
        } else {
            io::Read::read_exact(&mut file, &mut mem)?;
        }
        Ok(FileFlash { file, mem })
    }

    fn range(sector: u8, offset: u32, len: usize) -> io::Result<usize> {
        if sector > 1 || offset as usize + len > SECTOR_SIZE as usize {
            return Err(io::Error::new(io::ErrorKind::InvalidInput, "outside the journal sectors"));
        }
        Ok(sector as usize * SECTOR_SIZE as usize + offset as usize)
    }
}

impl Flash for FileFlash {
    const SECTOR_SIZE: u32 = SECTOR_SIZE;
    type Error = io::Error;

    fn erase(&mut self, sector: u8) -> io::Result<()> {
        let at = Self::range(sector, 0, SECTOR_SIZE as usize)?;
        let bytes = &mut self.mem[at..at + SECTOR_SIZE as usize];
        bytes.fill(0xFF);
        self.file.write_all_at(bytes, at as u64)?;
        self.file.sync_data()
    }

    fn program(&mut self, sector: u8, offset: u32, data: &[u8]) -> io::Result<()> {
        let at = Self::range(sector, offset, data.len())?;
        let bytes = &mut self.mem[at..at + data.len()];
        bytes.iter_mut().zip(data).for_each(|(m, d)| *m &= d);
        self.file.write_all_at(bytes, at as u64)?;
        self.file.sync_data()
    }

    fn read(&self, sector: u8, offset: u32, buf: &mut [u8]) {
        match Self::range(sector, offset, buf.len()) {
            Ok(at) => buf.copy_from_slice(&self.mem[at..at + buf.len()]),
            Err(_) => buf.fill(0),
        }
    }
}

/// The state file of one station.
#[derive(Debug)]
pub struct StateFile {
    path: PathBuf,
    journal: Journal<FileFlash>,
    /// The address pair as stored (or as configured while nothing is stored).
    stored: (u8, bool),
}

/// The state file of the station configured at `address`: `base` itself for a single
/// station, `base.<address>` when there are several.
pub fn path_for(base: &str, address: u8, several: bool) -> PathBuf {
    if several {
        PathBuf::from(format!("{base}.{address}"))
    } else {
        PathBuf::from(base)
    }
}

impl StateFile {
    /// Open (or create) the state file at `path`.
    pub fn open(path: PathBuf) -> io::Result<StateFile> {
        let journal = Journal::new(FileFlash::open(&path)?);
        let stored = journal.load::<StationAddress>().map_or((0xFF, false), |a| (a.address, a.no_add_chg));
        Ok(StateFile { path, journal, stored })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The stored station address.
    pub fn address(&self) -> Option<StationAddress> {
        self.journal.load()
    }

    /// The stored I&M1–4.
    pub fn im(&self) -> Option<ImData> {
        self.journal.load()
    }

    /// At start, before the line opens: the stored address (with No_Add_Chg) and I&M1–4 into
    /// the station's node (`module`: the station's only module, as configured). Returns what
    /// was restored, for the log.
    pub fn restore(&mut self, node: &mut Node, module: Option<&'static Module>) -> String {
        let mut what = Vec::new();
        match self.address() {
            Some(a) => {
                *node.slave_mut() = DpSlave::with_address_lock(&pbcard::card::SLAVE, a.address, a.no_add_chg);
                node.slave_mut().require_module(module);
                what.push(format!("station address {} (No_Add_Chg {})", a.address, a.no_add_chg as u8));
            }
            None => self.stored = (node.slave().address(), node.slave().no_add_chg()),
        }
        if let Some(d) = self.im() {
            node.im_mut().set_data(d);
            what.push("I&M1-4".into());
        }
        if what.is_empty() {
            format!("state file {}: nothing stored yet", self.path.display())
        } else {
            format!("state file {}: restored {}", self.path.display(), what.join(", "))
        }
    }

    /// After each application step: store a new address (Set_Slave_Add, the DPM) and I&M1–4
    /// a master wrote. Returns the log lines.
    pub fn persist(&mut self, node: &mut Node) -> Vec<String> {
        let mut log = Vec::new();
        let pair = (node.slave().address(), node.slave().no_add_chg());
        if pair != self.stored {
            self.stored = pair;
            let r = self.journal.save(&StationAddress { address: pair.0, no_add_chg: pair.1 });
            log.push(self.outcome(&format!("station address {} (No_Add_Chg {})", pair.0, pair.1 as u8), r));
        }
        if let Some(d) = node.im_mut().take_changed() {
            let r = self.journal.save(&d);
            log.push(self.outcome("I&M1-4", r));
        }
        log
    }

    fn outcome(&self, what: &str, r: Result<bool, StoreError<io::Error>>) -> String {
        match r {
            Ok(_) => format!("{what} stored in {}", self.path.display()),
            Err(e) => format!("storing {what} in {} failed: {e:?}", self.path.display()),
        }
    }
}

/// `--state`: open every station's file and restore it into the station (nothing without
/// `--state`). Returns the files, in the order of `stations`, and the log lines.
pub fn open_all(opts: &crate::Options, stations: &mut [crate::Station]) -> io::Result<(Vec<StateFile>, Vec<String>)> {
    let Some(base) = &opts.state else { return Ok((Vec::new(), Vec::new())) };
    let several = stations.len() > 1;
    let mut files = Vec::with_capacity(stations.len());
    let mut log = Vec::new();
    for st in stations.iter_mut() {
        let mut f = StateFile::open(path_for(base, st.config.address, several))?;
        let msg = f.restore(&mut st.node, st.config.module);
        // The line answers from the staging the station published when it was built (the
        // configured address): republish it now, or a request to the restored address that
        // comes before the first application step is dropped by the fast path's DA filter.
        st.publish(pbcard::dp::Events::ADDRESS_CHANGED);
        log.push(format!("{} {msg}", st.prefix()));
        files.push(f);
    }
    for (i, a) in stations.iter().enumerate() {
        let addr = a.node.slave().address();
        if let Some(b) = stations[..i].iter().find(|b| b.node.slave().address() == addr) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "stations {} and {} would both be at address {addr} (from {})",
                    b.config.address,
                    a.config.address,
                    files[i].path().display()
                ),
            ));
        }
    }
    Ok((files, log))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let p = std::env::temp_dir().join(format!("pbcard-state-{}-{name}", std::process::id()));
        let _ = std::fs::remove_file(&p);
        p
    }

    #[test]
    fn a_new_file_is_blank_and_keeps_what_is_saved() {
        let p = temp("blank");
        let mut j = Journal::new(FileFlash::open(&p).unwrap());
        assert_eq!(std::fs::metadata(&p).unwrap().len(), FILE_LEN);
        assert_eq!(j.load::<StationAddress>(), None);
        let mut im = ImData::DEFAULT;
        im.records[0][..4].copy_from_slice(b"Pump");
        j.save(&StationAddress { address: 9, no_add_chg: true }).unwrap();
        j.save(&im).unwrap();
        drop(j);
        let j = Journal::new(FileFlash::open(&p).unwrap());
        assert_eq!(j.load::<StationAddress>(), Some(StationAddress { address: 9, no_add_chg: true }));
        assert_eq!(j.load::<ImData>(), Some(im));
        std::fs::remove_file(&p).unwrap();
    }

    #[test]
    fn many_saves_compact_within_the_file() {
        let p = temp("compact");
        let mut j = Journal::new(FileFlash::open(&p).unwrap());
        let mut im = ImData::DEFAULT;
        for i in 0..200u32 {
            im.records[3][..4].copy_from_slice(&i.to_be_bytes());
            j.save(&im).unwrap();
            j.save(&StationAddress { address: (i % 126) as u8, no_add_chg: false }).unwrap();
        }
        drop(j);
        let j = Journal::new(FileFlash::open(&p).unwrap());
        assert_eq!(j.load::<ImData>(), Some(im));
        assert_eq!(j.load::<StationAddress>().map(|a| a.address), Some((199 % 126) as u8));
        std::fs::remove_file(&p).unwrap();
    }

    #[test]
    fn a_file_of_another_size_is_refused_and_left_alone() {
        let p = temp("other");
        std::fs::write(&p, b"not a journal").unwrap();
        let e = FileFlash::open(&p).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert_eq!(std::fs::read(&p).unwrap(), b"not a journal");
        std::fs::remove_file(&p).unwrap();
    }

    #[test]
    fn paths() {
        assert_eq!(path_for("/tmp/s", 5, false), PathBuf::from("/tmp/s"));
        assert_eq!(path_for("/tmp/s", 5, true), PathBuf::from("/tmp/s.5"));
    }
}
