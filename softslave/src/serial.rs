//! The serial line: a tty opened raw and non-blocking at any PROFIBUS rate (Linux `termios2`,
//! `BOTHER`), 8E1 when the device accepts even parity, 8N1 otherwise (a pseudo-terminal
//! refuses `PARENB`; its bytes pass unchanged). The only `unsafe` of the soft slave lives
//! here: `ioctl`, `ppoll` and the pseudo-terminal calls of libc.

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::os::fd::{AsRawFd, RawFd};
use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
use std::time::Duration;

use pbcard::time::Baudrate;

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
        Ok(Port { file, _peer: None, path: path.to_string(), parity, pty, speed })
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
        Ok(Port { file: master, _peer: Some(peer), path: name, parity: false, pty: true, speed })
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
