//! Shared by the fuzz targets: the input reader and the `PBCARD_FUZZ_TRACE` switch.
#![allow(dead_code)]

/// Reads the fuzz input front to back; zeros once it is used up.
pub struct Src<'a>(pub &'a [u8]);

impl<'a> Src<'a> {
    /// A reader over `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Src(data)
    }
    /// The next byte (0 at the end).
    pub fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }
    /// The next two bytes, big-endian.
    pub fn u16(&mut self) -> u16 {
        u16::from_be_bytes([self.u8(), self.u8()])
    }
    /// The next `n` bytes (fewer at the end).
    pub fn bytes(&mut self, n: usize) -> &'a [u8] {
        let n = n.min(self.0.len());
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        a
    }
    /// Whether the input is used up.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// `PBCARD_FUZZ_TRACE=1 cargo fuzz run <target> <input>` makes the targets print what they
/// do (for triaging a crash or checking what a seed does).
pub fn trace() -> bool {
    static T: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *T.get_or_init(|| std::env::var_os("PBCARD_FUZZ_TRACE").is_some())
}

/// `eprintln!` when [`trace`] is on.
#[allow(unused_macros)]
macro_rules! trace {
    ($($t:tt)*) => {
        if $crate::src::trace() {
            eprintln!($($t)*);
        }
    };
}

/// Repair the FCS and the end delimiter of a raw frame whose header announces a length it
/// holds (cut to that length), so the frame gets past those checks to the ones after them.
pub fn repair_frame(f: &mut Vec<u8>) {
    if let Ok(Some(len)) = pbcard::fdl::telegram::frame_len(f) {
        if len <= f.len() && len >= 6 {
            f.truncate(len);
            pbcard::fdl::telegram::finish(f, len);
            f[len - 1] = pbcard::fdl::telegram::ED;
        }
    }
}
