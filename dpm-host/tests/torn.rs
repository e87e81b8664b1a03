//! Torn reads: the card writes a block (tail, payload, head — pbcard's order) while the host
//! reads it through the transport, at every point of the read; the host retries and returns
//! the old or the new content, never a mix. DRIVE_CMD + OUTPUTS are returned as one card
//! cycle's pair.
//!
//! These tests stay on memory-level transports (`Tearing`, `AlwaysTorn`): they are about a
//! read that the card's writes cut at a byte, which only a memory transport can produce. Over
//! the SPI frames a block read is one READ frame (`SpiHost`: up to 1024 data bytes, a
//! whole block), the card copies it from the image in one piece and protects it with a CRC
//! (a damaged reply is asked again, never taken), so a read through SPI is atomic per
//! transaction; and the in-process card (`Loopback`) steps only between host calls. The
//! retry logic under test is the `Host`'s own and the same over every transport. The pairing
//! of DRIVE_CMD with OUTPUTS across two reads (two frames over SPI) runs over both transports
//! in `a_command_never_paired_with_its_outputs_is_not_returned`.

#[macro_use]
mod common;

use common::Image;
use dpm_host::layout;
use dpm_host::*;
use pbcard::dpm::Dpm;

/// The card's pending byte writes, applied while the host reads: `plan` says at which byte of
/// which read call how many steps happen; after `flush_at_call` everything left is applied.
struct Tearing {
    mem: Dpm,
    steps: Vec<(usize, u8)>,
    done: usize,
    plan: Vec<(usize, usize, usize)>,
    flush_at_call: usize,
    call: usize,
    armed: bool,
}

impl Tearing {
    fn apply(&mut self, n: usize) {
        for _ in 0..n {
            if let Some(&(at, v)) = self.steps.get(self.done) {
                self.mem.as_bytes_mut()[at] = v;
                self.done += 1;
            }
        }
    }
}

impl Transport for Tearing {
    fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError> {
        if !self.armed {
            buf.copy_from_slice(&self.mem.as_bytes()[offset as usize..][..buf.len()]);
            return Ok(());
        }
        if self.call >= self.flush_at_call {
            self.apply(self.steps.len());
        }
        for (i, b) in buf.iter_mut().enumerate() {
            let due: usize = self.plan.iter().filter(|p| p.0 == self.call && p.1 == i).map(|p| p.2).sum();
            self.apply(due);
            *b = self.mem.as_bytes()[offset as usize + i];
        }
        let after: usize = self.plan.iter().filter(|p| p.0 == self.call && p.1 >= buf.len()).map(|p| p.2).sum();
        self.apply(after);
        self.call += 1;
        Ok(())
    }
    fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError> {
        self.mem.as_bytes_mut()[offset as usize..][..data.len()].copy_from_slice(data);
        Ok(())
    }
}

/// The card's byte writes turning `old` into `new` for one block, in the card's order.
fn card_order(old: &Dpm, new: &Dpm, start: usize, len: usize) -> Vec<(usize, u8)> {
    let _ = old;
    let idx = (len - 2..len).chain(2..len - 2).chain(0..2);
    idx.map(|i| (start + i, new.as_bytes()[start + i])).collect()
}

fn cmd(setpoint: i16, outputs_seq: u16) -> DriveCommandImage {
    DriveCommandImage {
        command: DriveCommand {
            flags: CommandFlags::RUN | CommandFlags::FIELDBUS_CONTROL,
            speed_setpoint: setpoint,
            fault_resets: setpoint as u8,
            comm_loss_reaction: 0,
        },
        operate_mode: layout::operate_mode::PROFIDRIVE,
        telegram: Telegram::Standard(1),
        outputs_seq,
        extra: PzdWords::new(&[setpoint as u16; 16]).unwrap(),
    }
}

#[test]
fn a_command_read_during_the_cards_write_is_old_or_new_never_a_mix() {
    let mut old = Dpm::new();
    let (old_cmd, new_cmd) = (cmd(0x1111, 0), cmd(0x2222, 0));
    old.card().write_drive_command(&old_cmd);
    let mut new = old.clone();
    new.card().write_drive_command(&new_cmd);
    let (s, n) = (layout::drive_cmd::START, layout::drive_cmd::LEN);
    let steps = card_order(&old, &new, s, n);
    let m = steps.len();
    let (mut olds, mut news, mut retried, mut cases) = (0, 0, 0, 0);
    let mut run = |plan: Vec<(usize, usize, usize)>| {
        let mem = old.clone();
        let t = Tearing { mem, steps: steps.clone(), done: 0, plan, flush_at_call: 1, call: 0, armed: false };
        let mut host = Host::open(t, Options::DEFAULT).unwrap();
        host.transport_mut().armed = true; // open's reads do not count
        let (seq, got) = host.read_command().expect("retried until consistent");
        if got == old_cmd {
            assert_eq!(seq, 1);
            olds += 1;
        } else {
            assert_eq!((seq, got), (2, new_cmd), "a mix was returned");
            news += 1;
        }
        retried += (host.stats().torn_retries > 0) as u32;
        cases += 1;
    };
    // One cut: `a` card steps happen just before byte `j` of the host's read.
    for j in 0..=n {
        for a in 0..=m {
            run(vec![(0, j, a)]);
        }
    }
    // Two cuts inside the read.
    for j1 in (0..=n).step_by(3) {
        for j2 in (j1..=n).step_by(5) {
            for a in (0..=m).step_by(4) {
                for b in (0..=m - a).step_by(7) {
                    run(vec![(0, j1, a), (0, j2, b)]);
                }
            }
        }
    }
    assert!(olds > 0 && news > 0 && retried > 0, "old {olds}, new {news}, retried {retried} of {cases}");
}

#[test]
fn command_and_outputs_come_from_one_card_cycle() {
    let mut old = Dpm::new();
    let o1 = ProcessData::new(Telegram::Standard(1), PdFlags::DATA_EXCHANGE, &[0x04, 0x7E, 0x11, 0x11]);
    let s1 = old.card().write_outputs(&o1);
    old.card().write_drive_command(&cmd(0x1111, s1));
    let mut new = old.clone();
    let o2 = ProcessData::new(Telegram::Standard(1), PdFlags::DATA_EXCHANGE, &[0x04, 0x7F, 0x22, 0x22]);
    let s2 = new.card().write_outputs(&o2);
    new.card().write_drive_command(&cmd(0x2222, s2));
    // The card writes OUTPUTS, then DRIVE_CMD.
    let mut steps = card_order(&old, &new, layout::outputs::START, layout::outputs::LEN);
    steps.extend(card_order(&old, &new, layout::drive_cmd::START, layout::drive_cmd::LEN));
    let m = steps.len();
    let (mut unpaired, mut olds, mut news) = (0, 0, 0);
    // Host calls: 0 = OUTPUTS, 1 = DRIVE_CMD, 2.. = retries. Card steps at any byte of the
    // first two calls, the rest before call 3.
    for c in 0..2 {
        let len = if c == 0 { layout::outputs::LEN } else { layout::drive_cmd::LEN };
        for j in (0..=len).step_by(2) {
            for a in 0..=m {
                let t = Tearing {
                    mem: old.clone(),
                    steps: steps.clone(),
                    done: 0,
                    plan: vec![(c, j, a)],
                    flush_at_call: 3,
                    call: 0,
                    armed: false,
                };
                let mut host = Host::open(t, Options::DEFAULT).unwrap();
                host.transport_mut().armed = true;
                let p = host.read_process_data().expect("a pair within the attempts");
                let pair = (p.outputs.bytes().to_vec(), p.command.command.speed_setpoint);
                if pair == (o1.bytes().to_vec(), 0x1111) {
                    assert_eq!((p.outputs.seq, p.command.outputs_seq), (s1, s1));
                    olds += 1;
                } else {
                    assert_eq!(pair, (o2.bytes().to_vec(), 0x2222), "outputs and command of two cycles");
                    assert_eq!((p.outputs.seq, p.command.outputs_seq), (s2, s2));
                    news += 1;
                }
                unpaired += (host.stats().unpaired_retries > 0) as u32;
            }
        }
    }
    assert!(unpaired > 0 && olds > 0 && news > 0, "unpaired {unpaired}, old {olds}, new {news}");
}

/// A card that is always in the middle of a write: the host gives up, returns nothing.
struct AlwaysTorn(Dpm, u16);

impl Transport for AlwaysTorn {
    fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError> {
        DpmTransport::new(&mut self.0).read(offset, buf)?;
        // The tail of every sequenced block read changes under the reader.
        if buf.len() > 16 {
            self.1 = self.1.wrapping_add(1);
            let n = buf.len();
            buf[n - 2..].copy_from_slice(&self.1.to_be_bytes());
            buf[..2].copy_from_slice(&self.1.wrapping_add(1).to_be_bytes());
        }
        Ok(())
    }
    fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError> {
        DpmTransport::new(&mut self.0).write(offset, data)
    }
}

#[test]
fn a_block_torn_on_every_attempt_returns_no_data() {
    let opts = Options { read_attempts: 5, ..Options::DEFAULT };
    let mut host = Host::open(AlwaysTorn(Dpm::new(), 0), opts).unwrap();
    assert!(matches!(host.read_command(), Err(Error::Torn(_))));
    assert!(matches!(host.read_outputs(), Err(Error::Torn(_))));
    assert!(matches!(host.status(), Err(Error::Torn(_))));
    assert!(matches!(host.read_process_data(), Err(Error::Torn(_))));
    let p = host.poll(Instant::from_millis(0));
    assert_eq!((p.report, p.error.map(|e| matches!(e, Error::Torn(_)))), (None, Some(true)));
    let s = host.stats();
    assert_eq!((s.torn_retries, s.torn_failures), (5 * 5, 5));
}

over_both! {
/// DRIVE_CMD names OUTPUTS sequence 99, OUTPUTS is at 1: the host retries, then refuses the
/// pair (over SPI: two READ frames per attempt).
fn a_command_never_paired_with_its_outputs_is_not_returned(via) {
    let mut dpm = Dpm::new();
    dpm.card().write_outputs(&ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0; 4]));
    dpm.card().write_drive_command(&cmd(5, 99));
    let image = Image::new(via, dpm);
    let mut host = Host::open(image.transport(), Options::DEFAULT).unwrap();
    assert_eq!(host.read_process_data(), Err(Error::Unpaired { command_for: 99, outputs: 1 }));
    assert_eq!(host.stats().unpaired_retries, 8);
    // 0 = a command not tied to outputs: taken as it is.
    image.borrow_mut().card().write_drive_command(&cmd(5, 0));
    assert_eq!(host.read_process_data().unwrap().command.command.speed_setpoint, 5);
    image.assert_frames_crossed();
}
}
