//! Stable id → slot of the event core. Ids are labels (any u64, docs/model.md §2): a
//! user's bodies may be numbered 0, 1, … or 4e9 and u64::MAX. The small ids — those
//! below about twice the slot count, which is every id of a generated cloud and of the
//! fragments after it — sit in a dense table read with one load; any other id goes to a
//! hash map. Memory is O(bodies) whatever the ids are (a dense table indexed by any id
//! once asked for 4 TB for an id of 1e12).

use std::collections::HashMap;

/// No slot.
pub const NONE: u32 = u32::MAX;

/// Stable id → slot.
#[derive(Debug, Clone, Default)]
pub struct SlotIds {
    /// `dense[id]` for ids below `dense.len()`; NONE where no body has that id.
    dense: Vec<u32>,
    /// Every other id with a body.
    sparse: HashMap<u64, u32>,
}

/// Ids below `DENSE_SLACK + 2 × slots` go to the dense table (a few kB for a tiny cloud).
const DENSE_SLACK: u64 = 1024;

impl SlotIds {
    /// A table for about `bodies` bodies.
    pub fn with_capacity(bodies: usize) -> Self {
        Self {
            dense: Vec::with_capacity(bodies),
            sparse: HashMap::new(),
        }
    }

    /// The slot of `id`, if it has one.
    #[inline]
    pub fn get(&self, id: u64) -> Option<u32> {
        let s = match self.dense.get(id as usize) {
            Some(&s) if (id as usize as u64) == id => s,
            _ => *self.sparse.get(&id)?,
        };
        (s != NONE).then_some(s)
    }

    /// Give `id` the slot `slot`; `slots` is the core's slot count (it bounds the dense
    /// table to 2 × slots + 1024 entries).
    pub fn set(&mut self, id: u64, slot: u32, slots: usize) {
        if let Ok(k) = usize::try_from(id)
            && k < self.dense.len()
        {
            self.dense[k] = slot;
            return;
        }
        let bound = DENSE_SLACK + 2 * slots as u64;
        if id < bound {
            // Grow geometrically (within the bound), so the map is swept O(log N) times;
            // ids the map holds below the new length move into the table, where `get`
            // looks for them.
            let len = (id as usize + 1)
                .max(2 * self.dense.len())
                .min(bound as usize);
            self.dense.resize(len, NONE);
            let dense = &mut self.dense;
            self.sparse
                .retain(|&k, &mut s| match dense.get_mut(k as usize) {
                    Some(d) => {
                        *d = s;
                        false
                    }
                    None => true,
                });
            self.dense[id as usize] = slot;
        } else {
            self.sparse.insert(id, slot);
        }
    }

    /// `id` has no slot any more.
    pub fn clear(&mut self, id: u64) {
        if let Ok(k) = usize::try_from(id)
            && k < self.dense.len()
        {
            self.dense[k] = NONE;
        } else {
            self.sparse.remove(&id);
        }
    }

    /// Bytes held (the map counted at its capacity, 16 B an entry plus a control byte).
    pub fn bytes(&self) -> usize {
        self.dense.capacity() * 4 + self.sparse.capacity() * 17
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_ids_take_no_dense_room() {
        let mut t = SlotIds::default();
        t.set(u64::MAX, 0, 2);
        t.set(1_000_000_000_000, 1, 2);
        t.set(3, 2, 3);
        assert_eq!(t.get(u64::MAX), Some(0));
        assert_eq!(t.get(1_000_000_000_000), Some(1));
        assert_eq!(t.get(3), Some(2));
        assert_eq!(t.get(4), None);
        assert!(t.bytes() < 10_000, "{} bytes", t.bytes());
        t.clear(u64::MAX);
        t.clear(3);
        assert_eq!(t.get(u64::MAX), None);
        assert_eq!(t.get(3), None);
    }

    #[test]
    fn an_id_in_the_map_is_found_after_the_table_grows_past_it() {
        // Bodies inserted in space order: id 1500 arrives while there are few slots (to
        // the map), then the table grows past it. A run stalled on this once.
        let mut t = SlotIds::default();
        t.set(1500, 0, 1);
        for (slot, id) in (1..1200u32).zip(0u64..) {
            t.set(id, slot, slot as usize + 1);
        }
        t.set(1600, 1200, 1201);
        assert_eq!(t.get(1600), Some(1200));
        assert_eq!(t.get(1500), Some(0));
        t.clear(1500);
        assert_eq!(t.get(1500), None);
        for id in 0..1199 {
            assert_eq!(t.get(id), Some(id as u32 + 1));
        }
    }
}
