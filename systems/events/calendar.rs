//! The event calendar: an indexed binary min-heap holding at most one predicted event
//! per body slot (docs/model.md §4).
//!
//! Each body keeps only its earliest predicted event. Re-predicting a body replaces its
//! entry in place (O(log N)), so the heap never fills with a body's own outdated
//! predictions; events made stale by a *partner's* change are detected when popped,
//! through the partner's event counter. Ties in time are broken by the owner's stable
//! id, so the order of events never depends on memory layout.
//!
//! The heap's entries are 16 bytes (time and slot): the owners' ids, needed only to
//! break a tie, are the core's, and every call that reorders the heap is handed them.
//! An entry replaced by a later one sinks Floyd's way: the hole goes down the earlier
//! children to a leaf (one comparison per level), then the entry climbs back (a few
//! levels: a body's next event is usually late). Keys (time, id) are all distinct, so
//! the order events come out in does not depend on how the heap is shaped.

use super::cells::prefetch;

/// What a predicted event is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EventKind {
    /// Contact with the body in `slot`, whose event counter was `counter` when predicted.
    Contact {
        /// The partner's slot.
        slot: u32,
        /// The partner's event counter at the prediction.
        counter: u32,
    },
    /// The owner leaves its cell through face `axis` (0..3) towards `+1` or `-1`.
    Crossing {
        /// The face's axis, 0..3 (x, y, z).
        axis: u8,
        /// The direction, `+1` or `-1`.
        step: i8,
    },
    /// Predictions through periodic images hold only while partners have moved less
    /// than a fraction of the box relative to the owner: predict it again then.
    Refresh,
}

/// One predicted event of one body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    /// Absolute simulated time [s].
    pub time: f64,
    /// What happens then.
    pub kind: EventKind,
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    time: f64,
    slot: u32,
}

const ABSENT: u32 = u32::MAX;

/// Indexed min-heap of (time, owner id) over body slots.
#[derive(Debug, Default, Clone)]
pub struct Calendar {
    heap: Vec<Entry>,
    /// Position of each slot in `heap`, or ABSENT.
    position: Vec<u32>,
    /// What the event of each slot is (valid while the slot is in the heap; its time
    /// is in the heap entry).
    kinds: Vec<EventKind>,
}

impl Calendar {
    /// Number of bodies with a scheduled event.
    pub fn len(&self) -> usize {
        self.heap.len()
    }

    /// True when no event is pending.
    pub fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }

    /// Bytes held (for the memory figure).
    pub fn bytes(&self) -> usize {
        self.heap.capacity() * std::mem::size_of::<Entry>()
            + self.position.capacity() * 4
            + self.kinds.capacity() * std::mem::size_of::<EventKind>()
    }

    /// True when `a` is due before `b`: earlier, or as early with a smaller owner id
    /// (`ids`: the stable id of each slot's body).
    #[inline]
    fn before(a: &Entry, b: &Entry, ids: &[u64]) -> bool {
        a.time < b.time || (a.time == b.time && ids[a.slot as usize] < ids[b.slot as usize])
    }

    fn ensure(&mut self, slot: u32) {
        let need = slot as usize + 1;
        if self.position.len() < need {
            self.position.resize(need, ABSENT);
            self.kinds.resize(need, EventKind::Refresh);
        }
    }

    /// Schedule `event` for `slot`, replacing its previous event; `None` removes the
    /// slot's event. `ids`: the stable id of each slot's body (the tie-break).
    pub fn set(&mut self, slot: u32, event: Option<Event>, ids: &[u64]) {
        self.ensure(slot);
        match event {
            None => self.remove(slot, ids),
            Some(event) => {
                self.kinds[slot as usize] = event.kind;
                let entry = Entry {
                    time: event.time,
                    slot,
                };
                let at = self.position[slot as usize];
                if at == ABSENT {
                    self.heap.push(entry);
                    let last = self.heap.len() - 1;
                    self.position[slot as usize] = last as u32;
                    self.sift_up(last, ids);
                } else {
                    let at = at as usize;
                    let earlier = entry.time < self.heap[at].time;
                    self.heap[at] = entry;
                    if earlier {
                        self.sift_up(at, ids);
                    } else {
                        self.sift_down(at, ids);
                    }
                }
            }
        }
    }

    /// Remove the slot's event, if any.
    pub fn remove(&mut self, slot: u32, ids: &[u64]) {
        let Some(&at) = self.position.get(slot as usize) else {
            return;
        };
        if at == ABSENT {
            return;
        }
        let at = at as usize;
        self.position[slot as usize] = ABSENT;
        let last = self.heap.pop().expect("slot was in the heap");
        if at < self.heap.len() {
            self.heap[at] = last;
            self.position[last.slot as usize] = at as u32;
            self.sift_down(at, ids);
            self.sift_up(at, ids);
        }
    }

    /// The event scheduled for `slot`, if any.
    pub fn event_of(&self, slot: u32) -> Option<Event> {
        let &at = self.position.get(slot as usize)?;
        (at != ABSENT).then(|| Event {
            time: self.heap[at as usize].time,
            kind: self.kinds[slot as usize],
        })
    }

    /// Move every scheduled event to its slot's new number, in place: `new_of_old` is a
    /// permutation of 0..len (slots beyond the heap's reach included), `partner` maps a
    /// contact's partner slot to its new number or None when the partner is gone (the
    /// event then becomes a refresh: its owner is predicted again at that time). Keys do
    /// not change, so the heap order stands.
    pub fn renumber(&mut self, new_of_old: &[u32], partner: impl Fn(u32) -> Option<u32>) {
        // Slots past the permutation are past the last body: nothing is scheduled there
        // (an earlier renumbering dropped them).
        let len = new_of_old.len();
        self.position.resize(len, ABSENT);
        self.kinds.resize(len, EventKind::Refresh);
        for entry in &mut self.heap {
            entry.slot = new_of_old[entry.slot as usize];
        }
        for kind in &mut self.kinds {
            if let EventKind::Contact { slot, counter } = *kind {
                *kind = match partner(slot) {
                    Some(slot) => EventKind::Contact { slot, counter },
                    None => EventKind::Refresh,
                };
            }
        }
        permute_in_place(&mut self.position, new_of_old.to_vec());
        permute_in_place(&mut self.kinds, new_of_old.to_vec());
    }

    /// The earliest event: (slot, event).
    pub fn peek(&self) -> Option<(u32, Event)> {
        self.heap.first().map(|e| {
            (
                e.slot,
                Event {
                    time: e.time,
                    kind: self.kinds[e.slot as usize],
                },
            )
        })
    }

    /// The slot whose event is likely next after the top's: the earlier of the top's
    /// two children (unless the top's own next event comes sooner). A hint for
    /// prefetching; its kind is asked for here.
    pub fn runner_up(&self) -> Option<u32> {
        let next = match (self.heap.get(1), self.heap.get(2)) {
            (Some(l), Some(r)) => {
                if r.time < l.time {
                    r
                } else {
                    l
                }
            }
            (Some(l), None) => l,
            _ => return None,
        };
        prefetch(&self.kinds[next.slot as usize]);
        Some(next.slot)
    }

    /// Remove and return the earliest event.
    pub fn pop(&mut self, ids: &[u64]) -> Option<(u32, Event)> {
        let top = self.peek()?;
        self.remove(top.0, ids);
        Some(top)
    }

    /// Move the entry at `at` up to its place.
    fn sift_up(&mut self, at: usize, ids: &[u64]) {
        let entry = self.heap[at];
        self.climb(entry, at, 0, ids);
    }

    /// Place `entry` from the hole at `hole` upwards, no higher than `floor`: parents due
    /// after it move down into the hole.
    fn climb(&mut self, entry: Entry, mut hole: usize, floor: usize, ids: &[u64]) {
        while hole > floor {
            let parent = (hole - 1) / 2;
            if !Self::before(&entry, &self.heap[parent], ids) {
                break;
            }
            self.fill(hole, parent);
            hole = parent;
        }
        self.place(hole, entry);
    }

    /// Move the entry at `at` down to its place (Floyd's: see the module's text).
    fn sift_down(&mut self, at: usize, ids: &[u64]) {
        let n = self.heap.len();
        let entry = self.heap[at];
        let mut hole = at;
        loop {
            let left = 2 * hole + 1;
            if left >= n {
                break;
            }
            let right = left + 1;
            let child = if right < n && Self::before(&self.heap[right], &self.heap[left], ids) {
                right
            } else {
                left
            };
            self.fill(hole, child);
            hole = child;
        }
        self.climb(entry, hole, at, ids);
    }

    /// Move the entry at `from` into the hole at `hole`.
    #[inline]
    fn fill(&mut self, hole: usize, from: usize) {
        let moved = self.heap[from];
        self.place(hole, moved);
    }

    #[inline]
    fn place(&mut self, at: usize, entry: Entry) {
        self.heap[at] = entry;
        self.position[entry.slot as usize] = at as u32;
    }
}

/// Move `v[i]` to `v[target[i]]` for every i, in place (`target` a permutation).
pub fn permute_in_place<T>(v: &mut [T], mut target: Vec<u32>) {
    assert_eq!(v.len(), target.len(), "a permutation of the whole slice");
    for i in 0..v.len() {
        while target[i] as usize != i {
            let j = target[i] as usize;
            v.swap(i, j);
            target.swap(i, j);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng, rngs::StdRng};

    fn at(time: f64) -> Option<Event> {
        Some(Event {
            time,
            kind: EventKind::Crossing { axis: 0, step: 1 },
        })
    }

    /// Random sets and removals, then every pop: in order of (time, owner id). With
    /// `ties`, times come from 8 values, so most comparisons fall to the ids (owner ids
    /// are a scramble of the slots, so slot order would not pass).
    fn check_random_updates(seed: u64, ties: bool) {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut cal = Calendar::default();
        let mut truth = vec![None; 200];
        let id_of = |slot: u32| (slot as u64 * 7919) % 211;
        let ids: Vec<u64> = (0..200).map(id_of).collect();
        for _ in 0..5000 {
            let slot = rng.random_range(0..200u32);
            if rng.random_bool(0.2) {
                cal.remove(slot, &ids);
                truth[slot as usize] = None;
            } else {
                let t = if ties {
                    rng.random_range(0..8u32) as f64
                } else {
                    rng.random_range(0.0..1.0)
                };
                cal.set(slot, at(t), &ids);
                truth[slot as usize] = Some(t);
            }
        }
        let mut expected: Vec<(f64, u64, u32)> = truth
            .iter()
            .enumerate()
            .filter_map(|(s, t)| t.map(|t| (t, id_of(s as u32), s as u32)))
            .collect();
        expected.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut got = Vec::new();
        while let Some((slot, e)) = cal.pop(&ids) {
            got.push((e.time, id_of(slot), slot));
        }
        assert_eq!(got, expected);
    }

    #[test]
    fn pops_in_time_order_after_random_updates_and_removals() {
        check_random_updates(3, false);
    }

    #[test]
    fn equal_times_pop_by_owner_id_after_random_updates_and_removals() {
        for seed in 0..4 {
            check_random_updates(seed, true);
        }
    }

    #[test]
    fn equal_times_pop_by_owner_id() {
        let mut cal = Calendar::default();
        let ids = [9, 4, 7];
        for slot in 0..3 {
            cal.set(slot, at(1.0), &ids);
        }
        let order: Vec<u32> = std::iter::from_fn(|| cal.pop(&ids).map(|x| x.0)).collect();
        assert_eq!(order, vec![1, 2, 0]);
    }
}
