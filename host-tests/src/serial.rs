//! A profirust PHY over any byte stream: a pseudo-terminal, a serial device in raw mode, a
//! TCP or Unix socket (QEMU's `-serial unix:…` / `-serial tcp:…` / `-serial pty`).
//!
//! profirust's own serial PHYs cannot open a pty (they force a low-latency ioctl and parity),
//! and a socket has no termios at all. [`StreamPhy`] implements
//! [`ProfibusPhy`](profirust::phy::ProfibusPhy) on top of any non-blocking
//! `Read + Write` stream, so the same code serves
//!
//! * a **DP master** (profirust's `FdlActiveStation`) talking to the firmware in QEMU over a
//!   socket ([`StreamPhy::connect_unix`], [`StreamPhy::connect_tcp`]);
//! * a **soft slave** or a master on a pseudo-terminal pair ([`Pty::open`]: one side keeps the
//!   master end, the peer opens [`Pty::path`]) or on a real serial device ([`StreamPhy::open_tty`],
//!   raw 8N1 — a pty has no parity; on a real line the adapter must do 8E1);
//! * scripted request/response exchanges without profirust ([`StreamPhy::request`]).
//!
//! Semantics, chosen for a half-duplex bus seen through a stream:
//!
//! * A transmission is "done" when the stream took all bytes (no line timing: pass
//!   `Instant`s from the wall clock and give profirust a generous slot time — QEMU's per-byte
//!   USART and a loaded host add milliseconds).
//! * Bytes still unread when a transmission starts are dropped (counted in
//!   [`PhyStats::rx_dropped`]): on an RS485 line they would have been over before our
//!   request, so they cannot be its answer — typically a late answer to a request the master
//!   already gave up on. Switch off with [`StreamPhy::keep_rx_on_transmit`].
//! * End of stream (the peer closed) reads as silence; [`StreamPhy::is_closed`] tells.
//!
//! Example (a master on QEMU's USART1 socket):
//!
//! ```no_run
//! use host_tests::serial::StreamPhy;
//! let phy = StreamPhy::connect_unix("/tmp/pb.sock", std::time::Duration::from_secs(5)).unwrap();
//! // fdl.poll(now, &mut phy, &mut dp) in a loop, `now` from std::time::Instant.
//! ```

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::os::fd::AsRawFd;
use std::os::unix::fs::OpenOptionsExt;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use pbcard::fdl::telegram::{self, Decoded};
use profirust::phy::ProfibusPhy;

/// Largest telegram plus slack (profirust's PHYs use the same size).
const TX_BUF: usize = 512;
/// Receive buffer limit: beyond this the oldest bytes are dropped (a peer that floods).
const RX_MAX: usize = 64 * 1024;

/// Byte counters of a [`StreamPhy`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PhyStats {
    /// Bytes read from the stream.
    pub rx_bytes: u64,
    /// Bytes written to the stream.
    pub tx_bytes: u64,
    /// Telegrams (transmissions) started.
    pub tx_telegrams: u64,
    /// Unread bytes dropped when a transmission started, or beyond the buffer limit.
    pub rx_dropped: u64,
}

/// A profirust PHY on a non-blocking byte stream (module documentation).
#[derive(Debug)]
pub struct StreamPhy<S: Read + Write> {
    io: S,
    rx: Vec<u8>,
    tx: Vec<u8>,
    tx_len: usize,
    tx_pos: usize,
    drop_rx_on_tx: bool,
    closed: bool,
    stats: PhyStats,
    trace: Option<Instant>,
    last_tx: Vec<u8>,
}

impl<S: Read + Write> StreamPhy<S> {
    /// Wrap a stream that is already in non-blocking mode (reads return `WouldBlock` when
    /// there is nothing).
    pub fn new(io: S) -> Self {
        StreamPhy {
            io,
            rx: Vec::with_capacity(1024),
            tx: vec![0; TX_BUF],
            tx_len: 0,
            tx_pos: 0,
            drop_rx_on_tx: true,
            closed: false,
            stats: PhyStats::default(),
            trace: std::env::var_os("PBCARD_PHY_TRACE").map(|_| Instant::now()),
            last_tx: Vec::new(),
        }
    }

    /// The last telegram sent (its number is [`PhyStats::tx_telegrams`]).
    pub fn last_tx(&self) -> &[u8] {
        &self.last_tx
    }

    /// Print every chunk received and every telegram sent to stderr with a timestamp (also
    /// switched on by the environment variable `PBCARD_PHY_TRACE`).
    pub fn with_trace(mut self) -> Self {
        self.trace = Some(Instant::now());
        self
    }

    fn note(&self, what: &str, bytes: &[u8]) {
        if let Some(t0) = self.trace {
            eprintln!("phy {:>10.3} ms {what} {}", t0.elapsed().as_secs_f64() * 1e3, crate::hex(bytes));
        }
    }

    /// Keep unread received bytes when a transmission starts (default: drop them).
    pub fn keep_rx_on_transmit(mut self) -> Self {
        self.drop_rx_on_tx = false;
        self
    }

    /// Counters.
    pub fn stats(&self) -> PhyStats {
        self.stats
    }

    /// The peer closed the stream (end of file, reset, hang-up).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The underlying stream.
    pub fn get_ref(&self) -> &S {
        &self.io
    }

    /// Read everything available into the receive buffer.
    fn fill(&mut self) {
        let mut buf = [0u8; 1024];
        loop {
            match self.io.read(&mut buf) {
                Ok(0) => {
                    self.closed = true;
                    return;
                }
                Ok(n) => {
                    self.note("RX", &buf[..n]);
                    self.stats.rx_bytes += n as u64;
                    self.rx.extend_from_slice(&buf[..n]);
                    if self.rx.len() > RX_MAX {
                        let excess = self.rx.len() - RX_MAX;
                        self.rx.drain(..excess);
                        self.stats.rx_dropped += excess as u64;
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                // A pty master reads EIO while no one holds the slave side open; sockets
                // report resets: both are "nobody there", i.e. silence.
                Err(_) => {
                    self.closed = true;
                    return;
                }
            }
        }
    }

    /// Write as much of the pending transmission as the stream takes.
    fn flush_tx(&mut self) {
        while self.tx_pos < self.tx_len {
            match self.io.write(&self.tx[self.tx_pos..self.tx_len]) {
                Ok(0) => {
                    self.closed = true;
                    break;
                }
                Ok(n) => {
                    self.tx_pos += n;
                    self.stats.tx_bytes += n as u64;
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(_) => {
                    // The peer is gone: the telegram is lost, as on a dead line.
                    self.closed = true;
                    self.tx_pos = self.tx_len;
                }
            }
        }
        if self.tx_pos >= self.tx_len {
            let _ = self.io.flush();
            self.tx_len = 0;
            self.tx_pos = 0;
        }
    }

    /// Send raw bytes at once (blocking until the stream took them; at most 1 s).
    pub fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        if self.drop_rx_on_tx {
            self.fill();
            self.stats.rx_dropped += self.rx.len() as u64;
            self.rx.clear();
        }
        self.note("TX", bytes);
        self.last_tx.clear();
        self.last_tx.extend_from_slice(bytes);
        let deadline = Instant::now() + Duration::from_secs(1);
        let mut pos = 0;
        while pos < bytes.len() {
            match self.io.write(&bytes[pos..]) {
                Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
                Ok(n) => pos += n,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock && Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_micros(100))
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        self.stats.tx_bytes += bytes.len() as u64;
        self.stats.tx_telegrams += 1;
        self.io.flush()
    }

    /// Everything received so far (and not yet consumed), emptied.
    pub fn take_received(&mut self) -> Vec<u8> {
        self.fill();
        std::mem::take(&mut self.rx)
    }

    /// Wait up to `timeout` for one complete telegram (SD1/SD2/SD3/SD4/SC, checked with
    /// pbcard's decoder) and return its bytes; bytes that cannot start a telegram are skipped.
    pub fn receive_telegram_within(&mut self, timeout: Duration) -> Option<Vec<u8>> {
        let deadline = Instant::now() + timeout;
        loop {
            self.fill();
            loop {
                match telegram::decode(&self.rx) {
                    Decoded::Frame(_, n) => return Some(self.rx.drain(..n).collect()),
                    Decoded::Incomplete => break,
                    Decoded::Invalid(_) => {
                        self.rx.remove(0);
                        self.stats.rx_dropped += 1;
                    }
                }
            }
            if Instant::now() >= deadline || self.closed {
                return None;
            }
            std::thread::sleep(Duration::from_micros(50));
        }
    }

    /// A scripted exchange: send `frame`, wait up to `timeout` for one telegram back.
    pub fn request(&mut self, frame: &[u8], timeout: Duration) -> io::Result<Option<Vec<u8>>> {
        self.send(frame)?;
        Ok(self.receive_telegram_within(timeout))
    }
}

impl StreamPhy<UnixStream> {
    /// Connect to a Unix socket that a server (QEMU `-serial unix:PATH,server=on,wait=off`)
    /// is about to create: retries until `timeout`.
    pub fn connect_unix(path: impl AsRef<Path>, timeout: Duration) -> io::Result<Self> {
        let deadline = Instant::now() + timeout;
        loop {
            match UnixStream::connect(path.as_ref()) {
                Ok(s) => {
                    s.set_nonblocking(true)?;
                    return Ok(StreamPhy::new(s));
                }
                Err(e) if Instant::now() >= deadline => return Err(e),
                Err(_) => std::thread::sleep(Duration::from_millis(20)),
            }
        }
    }
}

impl StreamPhy<TcpStream> {
    /// Connect to a TCP server (QEMU `-serial tcp:127.0.0.1:PORT,server=on,wait=off`), retrying
    /// until `timeout`; Nagle is switched off.
    pub fn connect_tcp(addr: impl ToSocketAddrs + Copy, timeout: Duration) -> io::Result<Self> {
        let deadline = Instant::now() + timeout;
        loop {
            match TcpStream::connect(addr) {
                Ok(s) => {
                    s.set_nodelay(true)?;
                    s.set_nonblocking(true)?;
                    return Ok(StreamPhy::new(s));
                }
                Err(e) if Instant::now() >= deadline => return Err(e),
                Err(_) => std::thread::sleep(Duration::from_millis(20)),
            }
        }
    }
}

impl StreamPhy<File> {
    /// Open a terminal device (a pty slave such as `/dev/pts/7`, or a serial port) in raw
    /// mode, non-blocking. The line is set to raw 8N1 without flow control; the rate is left
    /// as it is (meaningless on a pty).
    pub fn open_tty(path: impl AsRef<Path>) -> io::Result<Self> {
        let f = OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
            .open(path.as_ref())?;
        make_raw(&f)?;
        Ok(StreamPhy::new(f))
    }
}

/// Put a terminal in raw mode (no echo, no line editing, no CR/LF translation, 8 bits).
fn make_raw(f: &File) -> io::Result<()> {
    let fd = f.as_raw_fd();
    // SAFETY: termios is plain data; tcgetattr fills it for a valid fd we own.
    let mut t: libc::termios = unsafe { std::mem::zeroed() };
    if unsafe { libc::tcgetattr(fd, &mut t) } != 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: cfmakeraw only modifies the struct; tcsetattr on our fd.
    unsafe { libc::cfmakeraw(&mut t) };
    t.c_cflag |= libc::CLOCAL | libc::CREAD;
    t.c_cc[libc::VMIN] = 0;
    t.c_cc[libc::VTIME] = 0;
    if unsafe { libc::tcsetattr(fd, libc::TCSANOW, &t) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// A pseudo-terminal pair: this side keeps the master end, a peer (another program, QEMU, a
/// soft slave) opens [`path`](Pty::path) like a serial port. The slave end is put in raw
/// mode and kept open here, so the line stays up while the peer (re)opens it.
#[derive(Debug)]
pub struct Pty {
    master: File,
    slave_keepalive: File,
    path: PathBuf,
}

impl Pty {
    /// Create a pair (posix_openpt).
    pub fn open() -> io::Result<Pty> {
        // SAFETY: plain libc calls on a descriptor we own and check.
        unsafe {
            let fd = libc::posix_openpt(libc::O_RDWR | libc::O_NOCTTY);
            if fd < 0 {
                return Err(io::Error::last_os_error());
            }
            let master = <File as std::os::fd::FromRawFd>::from_raw_fd(fd);
            if libc::grantpt(fd) != 0 || libc::unlockpt(fd) != 0 {
                return Err(io::Error::last_os_error());
            }
            let mut name = [0 as libc::c_char; 128];
            if libc::ptsname_r(fd, name.as_mut_ptr(), name.len()) != 0 {
                return Err(io::Error::last_os_error());
            }
            let path = PathBuf::from(std::ffi::CStr::from_ptr(name.as_ptr()).to_string_lossy().into_owned());
            if libc::fcntl(fd, libc::F_SETFL, libc::fcntl(fd, libc::F_GETFL) | libc::O_NONBLOCK) != 0 {
                return Err(io::Error::last_os_error());
            }
            let slave_keepalive = OpenOptions::new()
                .read(true)
                .write(true)
                .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
                .open(&path)?;
            make_raw(&slave_keepalive)?;
            Ok(Pty { master, slave_keepalive, path })
        }
    }

    /// The slave end's path (`/dev/pts/N`) for the peer.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A PHY on the master end (the pair stays alive as long as the PHY).
    pub fn into_phy(self) -> StreamPhy<PtyMaster> {
        StreamPhy::new(PtyMaster { master: self.master, _slave: self.slave_keepalive, path: self.path })
    }
}

/// The master end of a [`Pty`] (keeps the slave end open).
#[derive(Debug)]
pub struct PtyMaster {
    master: File,
    _slave: File,
    path: PathBuf,
}

impl PtyMaster {
    /// The slave end's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Read for PtyMaster {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.master.read(buf)
    }
}

impl Write for PtyMaster {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.master.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl<S: Read + Write> ProfibusPhy for StreamPhy<S> {
    fn poll_transmission(&mut self, _now: profirust::time::Instant) -> bool {
        if self.tx_len > 0 {
            self.flush_tx();
        }
        self.tx_len > 0
    }

    fn transmit_data<F, R>(&mut self, _now: profirust::time::Instant, f: F) -> R
    where
        F: FnOnce(&mut [u8]) -> (usize, R),
    {
        assert!(self.tx_len == 0, "transmit_data() while a transmission is pending");
        let (n, r) = f(&mut self.tx[..]);
        if n > 0 {
            if self.drop_rx_on_tx {
                self.fill();
                self.stats.rx_dropped += self.rx.len() as u64;
                self.rx.clear();
            }
            self.tx_len = n;
            self.tx_pos = 0;
            self.stats.tx_telegrams += 1;
            self.last_tx.clear();
            self.last_tx.extend_from_slice(&self.tx[..n]);
            self.note("TX", &self.last_tx);
            self.flush_tx();
        }
        r
    }

    fn receive_data<F, R>(&mut self, _now: profirust::time::Instant, f: F) -> R
    where
        F: FnOnce(&[u8]) -> (usize, R),
    {
        self.fill();
        let (drop, r) = f(&self.rx);
        let drop = drop.min(self.rx.len());
        self.rx.drain(..drop);
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pbcard::fdl::telegram::{emit, FunctionCode, Header};

    fn fdl_status(da: u8, sa: u8) -> Vec<u8> {
        let mut out = [0u8; 16];
        let n = emit(&mut out, &Header { da, sa, fc: FunctionCode(0x49), dsap: None, ssap: None }, &[]).unwrap();
        out[..n].to_vec()
    }

    fn ping_pong<A: Read + Write, B: Read + Write>(a: &mut StreamPhy<A>, b: &mut StreamPhy<B>) {
        let req = fdl_status(5, 2);
        a.send(&req).unwrap();
        assert_eq!(b.receive_telegram_within(Duration::from_secs(2)), Some(req.clone()));
        // profirust's side of the trait: transmit through the closure, receive, drop.
        let now = profirust::time::Instant::ZERO;
        b.transmit_data(now, |buf| {
            buf[..req.len()].copy_from_slice(&req);
            (req.len(), ())
        });
        assert!(!b.poll_transmission(now));
        let deadline = Instant::now() + Duration::from_secs(2);
        let mut got = Vec::new();
        while got.len() < req.len() && Instant::now() < deadline {
            a.receive_data(now, |buf| {
                got.extend_from_slice(buf);
                (buf.len(), ())
            });
        }
        assert_eq!(got, req);
    }

    #[test]
    fn socket_pair_carries_telegrams_both_ways() {
        let (x, y) = UnixStream::pair().unwrap();
        x.set_nonblocking(true).unwrap();
        y.set_nonblocking(true).unwrap();
        ping_pong(&mut StreamPhy::new(x), &mut StreamPhy::new(y));
    }

    #[test]
    fn pty_pair_is_raw_and_carries_every_byte_value() {
        let pty = Pty::open().unwrap();
        let mut peer = StreamPhy::open_tty(pty.path()).unwrap();
        let mut ours = pty.into_phy();
        ping_pong(&mut ours, &mut peer);
        // Raw: CR, LF, ^C, ^D, XON/XOFF and 0xFF pass unchanged, no echo.
        let all: Vec<u8> = (0..=255u8).collect();
        ours.send(&all).unwrap();
        let deadline = Instant::now() + Duration::from_secs(2);
        let mut got = Vec::new();
        while got.len() < all.len() && Instant::now() < deadline {
            got.extend(peer.take_received());
        }
        assert_eq!(got, all);
        std::thread::sleep(Duration::from_millis(20));
        assert!(ours.take_received().is_empty(), "echo on the pty");
    }

    #[test]
    fn unread_bytes_are_dropped_when_transmitting() {
        let (x, y) = UnixStream::pair().unwrap();
        x.set_nonblocking(true).unwrap();
        y.set_nonblocking(true).unwrap();
        let (mut a, mut b) = (StreamPhy::new(x), StreamPhy::new(y));
        b.send(&[0xE5, 0xE5]).unwrap();
        std::thread::sleep(Duration::from_millis(20));
        a.send(&fdl_status(5, 2)).unwrap();
        assert_eq!(a.stats().rx_dropped, 2);
        assert!(a.take_received().is_empty());
    }
}
