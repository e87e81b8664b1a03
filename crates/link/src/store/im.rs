//! I&M1–I&M4 (tag function / location, installation date, descriptor, signature; reference
//! §4.7, [`crate::dpv1::im`]) as a record of the card's [`Journal`](super::Journal): kept
//! across power loss in the same two sectors as the station address, with the same
//! guarantees (the previous or the new I&M1–4 after a cut at any moment; the address is never
//! disturbed by an I&M save, nor I&M by an address save).
//!
//! Record kind 0x02, payload [`ImData::LEN`] = 216 bytes: I&M1, I&M2, I&M3, I&M4, the 54
//! content bytes of each ([`ImData::encode`]; the 10-byte manufacturer header of the records
//! is not stored). Any bytes are I&M content (the card accepts any bytes a master writes).

use super::Record;
use crate::dpv1::im::ImData;

impl Record for ImData {
    const KIND: u8 = 0x02;
    const LEN: usize = ImData::LEN;
    fn encode(&self, out: &mut [u8]) {
        out.copy_from_slice(&ImData::encode(self));
    }
    fn decode(bytes: &[u8]) -> Option<Self> {
        let b: &[u8; ImData::LEN] = bytes.try_into().ok()?;
        Some(ImData::decode(b))
    }
}
