//! The event calendar: an indexed binary min-heap holding at most one predicted event
//! per body slot (docs/model.md §4).
//!
//! Each body keeps only its earliest predicted event. Re-predicting a body replaces its
//! entry in place (O(log N)), so the heap never fills with a body's own outdated
//! predictions; events made stale by a *partner's* change are detected when popped,
//! through the partner's event counter. Ties in time are broken by the owner's stable
//! id, so the order of events never depends on memory layout.

/// What a predicted event is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EventKind {
    /// Contact with the body in `slot`, whose event counter was `counter` when predicted.
    Contact { slot: u32, counter: u32 },
    /// The owner leaves its cell through face `axis` (0..3) towards `+1` or `-1`.
    Crossing { axis: u8, step: i8 },
    /// Predictions through periodic images hold only while partners have moved less
    /// than a fraction of the box relative to the owner: predict it again then.
    Refresh,
}

/// One predicted event of one body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    /// Absolute simulated time [s].
    pub time: f64,
    pub kind: EventKind,
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    time: f64,
    /// Stable id of the owner: the tie-break.
    id: u64,
    slot: u32,
}

impl Entry {
    #[inline]
    fn before(&self, other: &Entry) -> bool {
        self.time < other.time || (self.time == other.time && self.id < other.id)
    }
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

    pub fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }

    /// Bytes held (for the memory figure).
    pub fn bytes(&self) -> usize {
        self.heap.capacity() * std::mem::size_of::<Entry>()
            + self.position.capacity() * 4
            + self.kinds.capacity() * std::mem::size_of::<EventKind>()
    }

    fn ensure(&mut self, slot: u32) {
        let need = slot as usize + 1;
        if self.position.len() < need {
            self.position.resize(need, ABSENT);
            self.kinds.resize(need, EventKind::Refresh);
        }
    }

    /// Schedule `event` for `slot` (owner id `id`), replacing its previous event;
    /// `None` removes the slot's event.
    pub fn set(&mut self, slot: u32, id: u64, event: Option<Event>) {
        self.ensure(slot);
        match event {
            None => self.remove(slot),
            Some(event) => {
                self.kinds[slot as usize] = event.kind;
                let entry = Entry {
                    time: event.time,
                    id,
                    slot,
                };
                let at = self.position[slot as usize];
                if at == ABSENT {
                    self.heap.push(entry);
                    let last = self.heap.len() - 1;
                    self.position[slot as usize] = last as u32;
                    self.sift_up(last);
                } else {
                    let at = at as usize;
                    let earlier = entry.before(&self.heap[at]);
                    self.heap[at] = entry;
                    if earlier {
                        self.sift_up(at);
                    } else {
                        self.sift_down(at);
                    }
                }
            }
        }
    }

    /// Remove the slot's event, if any.
    pub fn remove(&mut self, slot: u32) {
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
            self.sift_down(at);
            self.sift_up(at);
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

    /// Remove and return the earliest event.
    pub fn pop(&mut self) -> Option<(u32, Event)> {
        let top = self.peek()?;
        self.remove(top.0);
        Some(top)
    }

    fn sift_up(&mut self, mut at: usize) {
        while at > 0 {
            let parent = (at - 1) / 2;
            if self.heap[at].before(&self.heap[parent]) {
                self.swap(at, parent);
                at = parent;
            } else {
                break;
            }
        }
    }

    fn sift_down(&mut self, mut at: usize) {
        let n = self.heap.len();
        loop {
            let (l, r) = (2 * at + 1, 2 * at + 2);
            let mut best = at;
            if l < n && self.heap[l].before(&self.heap[best]) {
                best = l;
            }
            if r < n && self.heap[r].before(&self.heap[best]) {
                best = r;
            }
            if best == at {
                break;
            }
            self.swap(at, best);
            at = best;
        }
    }

    fn swap(&mut self, a: usize, b: usize) {
        self.heap.swap(a, b);
        self.position[self.heap[a].slot as usize] = a as u32;
        self.position[self.heap[b].slot as usize] = b as u32;
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

    #[test]
    fn pops_in_time_order_after_random_updates_and_removals() {
        let mut rng = StdRng::seed_from_u64(3);
        let mut cal = Calendar::default();
        let mut truth = vec![None; 200];
        for _ in 0..5000 {
            let slot = rng.random_range(0..200u32);
            if rng.random_bool(0.2) {
                cal.remove(slot);
                truth[slot as usize] = None;
            } else {
                let t = rng.random_range(0.0..1.0);
                cal.set(slot, slot as u64, at(t));
                truth[slot as usize] = Some(t);
            }
        }
        let mut expected: Vec<(f64, u32)> = truth
            .iter()
            .enumerate()
            .filter_map(|(s, t)| t.map(|t| (t, s as u32)))
            .collect();
        expected.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut got = Vec::new();
        while let Some((slot, e)) = cal.pop() {
            got.push((e.time, slot));
        }
        assert_eq!(got, expected);
    }

    #[test]
    fn equal_times_pop_by_owner_id() {
        let mut cal = Calendar::default();
        cal.set(0, 9, at(1.0));
        cal.set(1, 4, at(1.0));
        cal.set(2, 7, at(1.0));
        let order: Vec<u32> = std::iter::from_fn(|| cal.pop().map(|x| x.0)).collect();
        assert_eq!(order, vec![1, 2, 0]);
    }
}
