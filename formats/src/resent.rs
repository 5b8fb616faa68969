//! Records a log holds twice: a block a recorder sent again after itself (a
//! retransmission), or two logs joined over the stretch they share. The readers keep the
//! records they accepted lately, each in the slot of its place in the log, and reject a
//! record that repeats the one kept at its place, as they reject one repeating the record
//! just before it (`rejected.duplicate_seq`). Kept, such a block goes back in time: its
//! records were "repaired" one interval on, the log grew by the block's length, and every
//! later sample was that much off the odometer's clock.

/// How many records back a repeat is recognised: 8192 records (82 s at 100 Hz, 819 s at
/// 10 Hz) in 8192 slots.
pub const RESENT_SLOTS: usize = 8192;

/// The records accepted lately, `K` each (what makes a record the same: a binary
/// record's `seq` and `t_us`, a text line's time and values) with `V` (where it was: a
/// text line's number), in the slot of their place in the log (a binary record's `seq`, a
/// text line's number of sample intervals from the first), held until a record
/// `RESENT_SLOTS` places on takes the slot.
#[derive(Debug)]
pub struct RecentRecords<K, V = ()> {
    /// Allocated at the first record kept.
    slots: Vec<Option<(K, V)>>,
}

impl<K, V> Default for RecentRecords<K, V> {
    fn default() -> Self {
        Self { slots: Vec::new() }
    }
}

impl<K: Copy + PartialEq, V: Copy> RecentRecords<K, V> {
    /// Keeps `key`, the record accepted at place `place`, with `value`.
    #[inline]
    pub fn keep(&mut self, place: u64, key: K, value: V) {
        if self.slots.is_empty() {
            self.slots = vec![None; RESENT_SLOTS];
        }
        self.slots[slot(place)] = Some((key, value));
    }

    /// The value kept with `key` at place `place`: a record seen again (`None`: not
    /// seen, or its slot taken since).
    pub fn seen(&self, place: u64, key: &K) -> Option<V> {
        match self.slots.get(slot(place)) {
            Some(Some((kept, value))) if kept == key => Some(*value),
            _ => None,
        }
    }
}

/// The slot of place `place`.
#[inline]
fn slot(place: u64) -> usize {
    (place % RESENT_SLOTS as u64) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A record is found at its place while no record `RESENT_SLOTS` places on took its
    /// slot, and only with its own key.
    #[test]
    fn a_record_is_held_until_its_slot_is_taken() {
        let mut recent = RecentRecords::default();
        assert_eq!(recent.seen(5, &(5u32, 50u64)), None);
        for place in 0..100u64 {
            recent.keep(place, (place as u32, place * 10), place + 1);
        }
        assert_eq!(recent.seen(5, &(5, 50)), Some(6));
        assert_eq!(recent.seen(5, &(5, 51)), None);
        assert_eq!(recent.seen(6, &(5, 50)), None);
        recent.keep(5 + RESENT_SLOTS as u64, (7, 7), 0);
        assert_eq!(recent.seen(5, &(5, 50)), None);
    }
}
