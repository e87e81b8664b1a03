//! Characters with parity or framing errors, as the Linux tty layer marks them.
//!
//! With `INPCK | PARMRK` (and neither `IGNPAR` nor `ISTRIP`) a character received with a
//! parity or framing error arrives as `FF 00 x`, a break as `FF 00 00`, and a good `FF` data
//! byte as `FF FF` (termios(3)). [`Parmrk`] turns that stream back into characters and
//! errors; with parity off (a pseudo-terminal) it passes bytes through.

/// One received character.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rx {
    /// A good character.
    Byte(u8),
    /// A character with a parity or framing error, or a break.
    Error,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Normal,
    Ff,
    FfZero,
}

/// Decoder of a `PARMRK` byte stream.
#[derive(Debug, Clone)]
pub struct Parmrk {
    marking: bool,
    state: State,
}

impl Parmrk {
    /// A decoder; `marking` = the port was set up with `PARMRK` (else bytes pass).
    pub fn new(marking: bool) -> Self {
        Parmrk { marking, state: State::Normal }
    }

    /// Decode `bytes`, calling `f` for each character or error.
    pub fn feed(&mut self, bytes: &[u8], mut f: impl FnMut(Rx)) {
        for &b in bytes {
            if !self.marking {
                f(Rx::Byte(b));
                continue;
            }
            self.state = match (self.state, b) {
                (State::Normal, 0xFF) => State::Ff,
                (State::Normal, b) => {
                    f(Rx::Byte(b));
                    State::Normal
                }
                (State::Ff, 0xFF) => {
                    f(Rx::Byte(0xFF));
                    State::Normal
                }
                (State::Ff, 0x00) => State::FfZero,
                (State::Ff, b) => {
                    // Not a sequence the tty layer produces: keep both bytes.
                    f(Rx::Byte(0xFF));
                    f(Rx::Byte(b));
                    State::Normal
                }
                (State::FfZero, _) => {
                    f(Rx::Error);
                    State::Normal
                }
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// What the tty layer delivers for `rx`.
    fn mark(rx: &[Rx]) -> Vec<u8> {
        let mut out = Vec::new();
        for r in rx {
            match *r {
                Rx::Byte(0xFF) => out.extend_from_slice(&[0xFF, 0xFF]),
                Rx::Byte(b) => out.push(b),
                Rx::Error => out.extend_from_slice(&[0xFF, 0x00, 0x5A]),
            }
        }
        out
    }

    fn decode(bytes: &[u8], marking: bool, chunk: usize) -> Vec<Rx> {
        let mut p = Parmrk::new(marking);
        let mut out = Vec::new();
        for c in bytes.chunks(chunk.max(1)) {
            p.feed(c, |r| out.push(r));
        }
        out
    }

    #[test]
    fn golden() {
        assert_eq!(
            decode(&[0x10, 0xFF, 0xFF, 0xFF, 0x00, 0x00, 0x16], true, 1),
            [Rx::Byte(0x10), Rx::Byte(0xFF), Rx::Error, Rx::Byte(0x16)]
        );
        assert_eq!(decode(&[0xFF, 0x00, 0x00], false, 3), [Rx::Byte(0xFF), Rx::Byte(0), Rx::Byte(0)]);
    }

    fn rx() -> impl Strategy<Value = Rx> {
        prop_oneof![any::<u8>().prop_map(Rx::Byte), Just(Rx::Byte(0xFF)), Just(Rx::Error)]
    }

    proptest! {
        #[test]
        fn marked_streams_decode_back(items in proptest::collection::vec(rx(), 0..60), chunk in 1usize..8) {
            prop_assert_eq!(decode(&mark(&items), true, chunk), items);
        }

        #[test]
        fn any_bytes_decode_without_panic(bytes in proptest::collection::vec(any::<u8>(), 0..80)) {
            let n = decode(&bytes, true, 3).len();
            prop_assert!(n <= bytes.len());
        }
    }
}
