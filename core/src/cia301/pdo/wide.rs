//! The payloads of CAN FD PDOs longer than 8 bytes that the engine must keep between two
//! events (feature `fd`): a synchronous RPDO's last frame until the SYNC, a type-252 TPDO's
//! sample until the RTR.
//!
//! **Why apart from the PDOs.** Every PDO keeps 8 bytes for this inline, which is all a classic
//! PDO needs; giving each 64 would grow every node built with `fd` by 56 bytes a PDO (a master
//! mirroring 512 TPDOs by 28 KiB) for the few wide synchronous PDOs a network has. So the wide
//! payloads share one bounded table of [`WIDE_PAYLOADS`] entries, which exists only on a node
//! on a CANopen FD network (on the heap with `alloc`, in place without).
//!
//! **When it is full** a further wide payload is not kept: the frame (or the sample) is dropped
//! and counted ([`WidePayloads::dropped`]), as a full transmit queue drops and counts; the
//! payloads already held are never displaced, so a PDO that holds one keeps it.

/// Wide payloads held at once.
pub const WIDE_PAYLOADS: usize = 8;

/// Key of RPDO slot `k`.
pub(super) const fn rx_key(k: usize) -> u32 {
    k as u32
}
/// Key of TPDO slot `k`.
pub(super) const fn tx_key(k: usize) -> u32 {
    0x1_0000 | k as u32
}

/// The table: (key, payload), at most [`WIDE_PAYLOADS`].
#[derive(Clone, Debug, Default)]
pub(crate) struct WidePayloads {
    held: heapless::Vec<(u32, [u8; 64]), WIDE_PAYLOADS>,
    dropped: u32,
}

impl WidePayloads {
    /// Keeps `payload` under `key`, replacing what the key held. False (counted) when the
    /// table is full.
    pub fn put(&mut self, key: u32, payload: &[u8; 64]) -> bool {
        if let Some((_, p)) = self.held.iter_mut().find(|(k, _)| *k == key) {
            *p = *payload;
            return true;
        }
        if self.held.push((key, *payload)).is_err() {
            self.dropped = self.dropped.wrapping_add(1);
            return false;
        }
        true
    }
    /// What `key` holds.
    pub fn get(&self, key: u32) -> Option<&[u8; 64]> {
        self.held.iter().find(|(k, _)| *k == key).map(|(_, p)| p)
    }
    /// Takes what `key` holds.
    pub fn take(&mut self, key: u32) -> Option<[u8; 64]> {
        let i = self.held.iter().position(|(k, _)| *k == key)?;
        Some(self.held.swap_remove(i).1)
    }
    /// Forgets everything (the PDOs stopped).
    pub fn clear(&mut self) {
        self.held.clear();
    }
    /// Wide payloads dropped because the table was full.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }
}

/// Where the engine keeps the table: on the heap where there is one, so that a node built with
/// `fd` but on a classic network carries one pointer; in place without an allocator.
#[cfg(feature = "alloc")]
pub(super) type WideHolder = alloc::boxed::Box<WidePayloads>;
#[cfg(not(feature = "alloc"))]
pub(super) type WideHolder = WidePayloads;

/// A new, empty table in its holder.
pub(super) fn holder() -> WideHolder {
    #[cfg(feature = "alloc")]
    return alloc::boxed::Box::default();
    #[cfg(not(feature = "alloc"))]
    WidePayloads::default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_table_drops_and_counts_and_keeps_what_it_holds() {
        let mut w = WidePayloads::default();
        for k in 0..WIDE_PAYLOADS {
            assert!(w.put(rx_key(k), &[k as u8; 64]));
        }
        assert!(w.put(rx_key(0), &[9; 64]), "a held key is replaced");
        assert!(!w.put(tx_key(0), &[1; 64]));
        assert_eq!(w.dropped(), 1);
        assert_eq!(w.get(rx_key(0)), Some(&[9; 64]));
        assert_eq!(w.take(rx_key(1)), Some([1; 64]));
        assert_eq!(w.take(rx_key(1)), None);
        assert!(w.put(tx_key(0), &[1; 64]), "room again");
    }
}
