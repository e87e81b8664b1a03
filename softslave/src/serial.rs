//! The serial line: a tty opened raw and non-blocking at any PROFIBUS rate (Linux `termios2`,
//! `BOTHER`), 8E1 when the device accepts even parity, 8N1 otherwise (a pseudo-terminal
//! refuses `PARENB`; its bytes pass unchanged). The only `unsafe` of the soft slave lives
//! here: `ioctl`, `ppoll` and the pseudo-terminal calls of libc.
//!
//! [`Port`] implements the board contract of the line (`pbcard::phy::port`, README
//! "Hardware"), with the fallbacks of a host process: a microsecond [`BitTimer`] from the
//! host's monotonic clock, no DE of its own ([`DriverEnable`]: the adapter switches
//! direction), a [`Transmitter`] that spins to its start instant and hands the bytes to the
//! tty driver, and a [`CharReceiver`] over non-blocking reads decoded by [`Parmrk`]. I/O errors
//! (a hung-up line) cannot go through the contract's methods: they are kept and returned by
//! [`Port::take_error`].

use std::collections::VecDeque;
use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::os::fd::{AsRawFd, RawFd};
use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
use std::time::{Duration, Instant as StdInstant};

use pbcard::phy::line::BitClock;
use pbcard::phy::port::{
    BitTimer, CharReceiver, DriverEnable, LineError, LineEvent, LineRate, Transmitter, TxError, UnsupportedRate,
};
use pbcard::time::{Baudrate, BitTimes, Instant};

use crate::parmrk::{Parmrk, Rx};

/// An open, configured serial line.
#[derive(Debug)]
pub struct Port {
    file: File,
    /// For a pseudo-terminal this program created: its other end, kept open so that reads
    /// do not fail while no peer has it open.
    _peer: Option<File>,
    path: String,
    parity: bool,
    pty: bool,
    speed: u32,
    rate: Baudrate,
    /// The origin of the [`BitTimer`] and of the events' times ([`Port::set_epoch`]).
    epoch: StdInstant,
    decoder: Parmrk,
    /// Decoded events not yet taken ([`CharReceiver::poll_event`]).
    events: VecDeque<LineEvent>,
    /// The first I/O error a contract method met ([`Port::take_error`]).
    error: Option<io::Error>,
}

impl Port {
    /// Open `path` (a tty) raw and non-blocking at `rate`.
    pub fn open(path: &str, rate: Baudrate) -> io::Result<Port> {
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
            .open(path)
            .map_err(|e| io::Error::new(e.kind(), format!("cannot open {path}: {e}")))?;
        let major = dev_major(file.metadata()?.rdev());
        let (parity, speed) = configure(file.as_raw_fd(), rate)
            .map_err(|e| io::Error::new(e.kind(), format!("{path} is not a usable serial device: {e}")))?;
        // Unix98 pseudo-terminal slaves have majors 136..=143 (Linux devices.txt).
        let pty = (136..=143).contains(&major);
        Ok(Port::new(file, None, path.to_string(), parity, pty, speed, rate))
    }

    /// Create a pseudo-terminal: this program uses the master side; the returned port's
    /// [`Port::path`] is the `/dev/pts/N` a DP master program opens.
    pub fn create_pty(rate: Baudrate) -> io::Result<Port> {
        // SAFETY: plain libc calls on a descriptor this function owns; ptsname_r writes at most
        // `buf.len()` bytes into `buf`.
        let (master, name) = unsafe {
            let fd = libc::posix_openpt(libc::O_RDWR | libc::O_NOCTTY | libc::O_NONBLOCK);
            if fd < 0 {
                return Err(io::Error::last_os_error());
            }
            let master = <File as std::os::fd::FromRawFd>::from_raw_fd(fd);
            if libc::grantpt(fd) != 0 || libc::unlockpt(fd) != 0 {
                return Err(io::Error::last_os_error());
            }
            let mut buf = [0 as libc::c_char; 128];
            let rc = libc::ptsname_r(fd, buf.as_mut_ptr(), buf.len());
            if rc != 0 {
                return Err(io::Error::from_raw_os_error(rc));
            }
            (master, std::ffi::CStr::from_ptr(buf.as_ptr()).to_string_lossy().into_owned())
        };
        let peer = OpenOptions::new().read(true).write(true).custom_flags(libc::O_NOCTTY).open(&name)?;
        // The line discipline of a pseudo-terminal lives on the slave side: make it raw.
        let (_, speed) = configure(peer.as_raw_fd(), rate)?;
        Ok(Port::new(master, Some(peer), name, false, true, speed, rate))
    }

    fn new(file: File, peer: Option<File>, path: String, parity: bool, pty: bool, speed: u32, rate: Baudrate) -> Port {
        Port {
            file,
            _peer: peer,
            path,
            parity,
            pty,
            speed,
            rate,
            epoch: StdInstant::now(),
            decoder: Parmrk::new(parity),
            events: VecDeque::new(),
            error: None,
        }
    }

    /// Count the [`BitTimer`] and the received characters' times from `epoch` (the run's
    /// start; default: when the port was opened).
    pub fn set_epoch(&mut self, epoch: StdInstant) {
        self.epoch = epoch;
    }

    /// The I/O error a contract method met (reading: a hung-up line; writing), once.
    pub fn take_error(&mut self) -> io::Result<()> {
        self.error.take().map_or(Ok(()), Err)
    }

    /// The [`BitTimer`] value of the host instant `t` (microseconds since the epoch, wrapping).
    pub fn ticks_at(&self, t: StdInstant) -> u32 {
        t.saturating_duration_since(self.epoch).as_micros() as u32
    }

    /// The protocol time of the host instant `t` (microseconds since the epoch).
    pub fn instant_at(&self, t: StdInstant) -> Instant {
        Instant::from_micros(t.saturating_duration_since(self.epoch).as_micros() as u64)
    }

    /// The device path (for a created pseudo-terminal: the path its peer opens).
    pub fn path(&self) -> &str {
        &self.path
    }
    /// Even parity is on (8E1); otherwise 8N1.
    pub fn parity(&self) -> bool {
        self.parity
    }
    /// A pseudo-terminal (no real line: no parity, no timing).
    pub fn is_pty(&self) -> bool {
        self.pty
    }
    /// The rate the device reports after configuration, in bit/s.
    pub fn speed(&self) -> u32 {
        self.speed
    }

    /// Wait until bytes can be read or `timeout` passed. Returns whether bytes are there; a
    /// hung-up line (the pseudo-terminal's other end closed, the adapter unplugged) is an error.
    pub fn wait_readable(&self, timeout: Duration) -> io::Result<bool> {
        let revents = wait(self.file.as_raw_fd(), libc::POLLIN, timeout)?;
        if revents & libc::POLLIN != 0 {
            Ok(true)
        } else if revents & (libc::POLLHUP | libc::POLLERR | libc::POLLNVAL) != 0 {
            Err(self.closed())
        } else {
            Ok(false)
        }
    }

    /// Read what is there (0 = nothing: a raw tty with VMIN = VTIME = 0 reads 0 bytes, not
    /// `EAGAIN`, when its queue is empty; a closed line shows in [`Port::wait_readable`]).
    pub fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self.file.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted => Ok(0),
            Err(e) if e.raw_os_error() == Some(libc::EIO) => Err(self.closed()),
            Err(e) => Err(e),
        }
    }

    fn closed(&self) -> io::Error {
        io::Error::new(io::ErrorKind::BrokenPipe, format!("{}: the other end of the line was closed", self.path))
    }

    /// Write all of `data` (waiting while the driver's buffer is full).
    pub fn write_all(&mut self, mut data: &[u8]) -> io::Result<()> {
        while !data.is_empty() {
            match self.file.write(data) {
                Ok(n) => data = &data[n..],
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    wait(self.file.as_raw_fd(), libc::POLLOUT, Duration::from_millis(100))?;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

impl LineRate for Port {
    fn rate(&self) -> Baudrate {
        self.rate
    }

    /// Reconfigure the tty (a created pseudo-terminal: its peer, where the line discipline
    /// lives) at `rate`; decoded characters not yet taken are dropped. A device that refuses
    /// the rate keeps the old one.
    fn set_rate(&mut self, rate: Baudrate) -> Result<(), UnsupportedRate> {
        let fd = self._peer.as_ref().map_or(self.file.as_raw_fd(), |p| p.as_raw_fd());
        let (parity, speed) = configure(fd, rate).map_err(|_| UnsupportedRate(rate))?;
        if self._peer.is_none() {
            self.parity = parity;
            self.decoder = Parmrk::new(parity);
        }
        self.speed = speed;
        self.rate = rate;
        self.events.clear();
        Ok(())
    }
}

/// Fallback: a host process has no bit timer: the counter is the host's monotonic clock in
/// microseconds since the epoch ([`Port::set_epoch`]), 1 MHz.
impl BitTimer for Port {
    fn clock(&self) -> BitClock {
        BitClock { hz: 1_000_000 }
    }

    fn ticks(&self) -> u32 {
        self.ticks_at(StdInstant::now())
    }
}

/// Fallback: the tty has no DE line of its own here — a USB-RS485 adapter switches direction
/// by itself (a pseudo-terminal has no line): both are no-ops.
impl DriverEnable for Port {
    fn enable(&mut self) {}
    fn disable(&mut self) {}
}

impl Transmitter for Port {
    /// Fallback: a host process has no compare interrupt: the port spins until the
    /// [`BitTimer`] has reached `not_before` (the caller, `crate::run`, calls it within 2 ms of
    /// the instant and checks first that no character arrived), then hands the bytes to the
    /// tty driver (waiting only while the driver's buffer is full). An I/O error is kept
    /// ([`Port::take_error`]) and reported as [`TxError::Busy`].
    fn start_tx(&mut self, bytes: &[u8], not_before: u32) -> Result<(), TxError> {
        if bytes.is_empty() || bytes.len() > pbcard::fdl::telegram::MAX_FRAME_LEN {
            return Err(TxError::BadLength);
        }
        while !self.reached(not_before) {
            std::hint::spin_loop();
        }
        self.write_all(bytes).map_err(|e| {
            self.error.get_or_insert(e);
            TxError::Busy
        })
    }

    /// Fallback: always `false` — the tty driver queues the bytes and reports no
    /// transmit-complete event (`tcdrain` would block).
    fn tx_busy(&self) -> bool {
        false
    }
}

impl CharReceiver for Port {
    /// One non-blocking read when no decoded event is left; every character of that read
    /// carries the read's time, no idle gap (`idle_before` 0: the host loop measures the
    /// silence itself). A marked character ([`Parmrk`]: parity or framing error, break) is a
    /// [`LineEvent::Error`] with `parity` and `framing` set (the tty does not tell them
    /// apart). A read error is kept ([`Port::take_error`]) and ends the events.
    fn poll_event(&mut self) -> Option<LineEvent> {
        if self.events.is_empty() && self.error.is_none() {
            let mut buf = [0u8; 512];
            match self.read(&mut buf) {
                Ok(n) => {
                    let at = self.instant_at(StdInstant::now());
                    let events = &mut self.events;
                    self.decoder.feed(&buf[..n], |rx| {
                        events.push_back(match rx {
                            Rx::Byte(byte) => LineEvent::Byte { byte, at, idle_before: BitTimes(0) },
                            Rx::Error => {
                                LineEvent::Error(LineError { parity: true, framing: true, ..Default::default() })
                            }
                        })
                    });
                }
                Err(e) => self.error = Some(e),
            }
        }
        self.events.pop_front()
    }
}

fn dev_major(rdev: u64) -> u64 {
    ((rdev >> 8) & 0xFFF) | ((rdev >> 32) & !0xFFF)
}

/// `ppoll` one descriptor; returns `revents` (0 on timeout or signal).
fn wait(fd: RawFd, events: libc::c_short, timeout: Duration) -> io::Result<libc::c_short> {
    let mut p = libc::pollfd { fd, events, revents: 0 };
    let ts = libc::timespec {
        tv_sec: timeout.as_secs().min(3600) as libc::time_t,
        tv_nsec: timeout.subsec_nanos() as libc::c_long,
    };
    // SAFETY: one valid pollfd, a valid timespec, no signal mask.
    let rc = unsafe { libc::ppoll(&mut p, 1, &ts, std::ptr::null()) };
    match rc {
        rc if rc > 0 => Ok(p.revents),
        0 => Ok(0),
        _ => {
            let e = io::Error::last_os_error();
            if e.kind() == io::ErrorKind::Interrupted {
                Ok(0)
            } else {
                Err(e)
            }
        }
    }
}

fn get(fd: RawFd) -> io::Result<libc::termios2> {
    // SAFETY: termios2 is plain data; TCGETS2 fills it.
    unsafe {
        let mut t: libc::termios2 = std::mem::zeroed();
        if libc::ioctl(fd, libc::TCGETS2, &mut t) < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(t)
    }
}

fn set(fd: RawFd, t: &libc::termios2) -> io::Result<()> {
    // SAFETY: TCSETS2 reads a valid termios2.
    if unsafe { libc::ioctl(fd, libc::TCSETS2, t) } < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// Raw mode at `rate`: try 8E1 with parity errors marked (`PARMRK`), fall back to 8N1.
/// Returns (parity on, speed read back).
fn configure(fd: RawFd, rate: Baudrate) -> io::Result<(bool, u32)> {
    let mut t = get(fd)?;
    t.c_iflag &= !(libc::IGNBRK
        | libc::BRKINT
        | libc::PARMRK
        | libc::ISTRIP
        | libc::INLCR
        | libc::IGNCR
        | libc::ICRNL
        | libc::IXON
        | libc::IXOFF
        | libc::IXANY
        | libc::INPCK
        | libc::IGNPAR);
    t.c_oflag &= !libc::OPOST;
    t.c_lflag &= !(libc::ECHO | libc::ECHONL | libc::ICANON | libc::ISIG | libc::IEXTEN);
    t.c_cflag &= !(libc::CSIZE
        | libc::PARENB
        | libc::PARODD
        | libc::CSTOPB
        | libc::CRTSCTS
        | libc::CBAUD
        | (libc::CBAUD << libc::IBSHIFT));
    t.c_cflag |= libc::CS8 | libc::CREAD | libc::CLOCAL | libc::BOTHER | (libc::BOTHER << libc::IBSHIFT);
    t.c_ispeed = rate.bits_per_second();
    t.c_ospeed = rate.bits_per_second();
    t.c_cc[libc::VMIN] = 0;
    t.c_cc[libc::VTIME] = 0;

    let mut even = t;
    even.c_cflag |= libc::PARENB;
    even.c_iflag |= libc::INPCK | libc::PARMRK;
    let parity = set(fd, &even).is_ok() && get(fd)?.c_cflag & libc::PARENB != 0;
    if !parity {
        set(fd, &t)?;
    }
    let back = get(fd)?;
    Ok((parity, back.c_ospeed))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The line contract over a pseudo-terminal: characters in as events with their time, a
    /// response out through the transmitter, the rate switched.
    #[test]
    fn contract_over_a_pty() {
        let mut port = Port::create_pty(Baudrate::B19200).unwrap();
        let mut peer =
            OpenOptions::new().read(true).write(true).custom_flags(libc::O_NOCTTY).open(port.path()).unwrap();
        assert_eq!(port.rate(), Baudrate::B19200);
        assert!(port.poll_event().is_none());
        peer.write_all(&[0x10, 0x02, 0xFF]).unwrap();
        assert!(port.wait_readable(Duration::from_secs(2)).unwrap());
        let mut got = Vec::new();
        while got.len() < 3 {
            match port.poll_event() {
                Some(LineEvent::Byte { byte, idle_before, .. }) => {
                    assert_eq!(idle_before, BitTimes(0));
                    got.push(byte);
                }
                Some(e) => panic!("unexpected {e:?}"),
                None => assert!(port.wait_readable(Duration::from_secs(2)).unwrap()),
            }
        }
        assert_eq!(got, [0x10, 0x02, 0xFF]);
        port.take_error().unwrap();

        // Due a little later: the transmitter waits for the instant, then writes.
        let t = StdInstant::now();
        let not_before = port.ticks().wrapping_add(2_000);
        port.start_tx(&[0xE5], not_before).unwrap();
        assert!(t.elapsed() >= Duration::from_millis(2));
        assert!(!port.tx_busy());
        // The peer is raw with VMIN = 0: a read may come back empty before the byte is there.
        let mut b = [0u8; 1];
        let deadline = StdInstant::now() + Duration::from_secs(2);
        while peer.read(&mut b).unwrap() == 0 {
            assert!(StdInstant::now() < deadline, "the response never reached the peer");
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(b, [0xE5]);
        assert_eq!(port.start_tx(&[], 0), Err(TxError::BadLength));

        port.set_rate(Baudrate::B1500k).unwrap();
        assert_eq!(port.rate(), Baudrate::B1500k);
    }
}
