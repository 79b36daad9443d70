//! Sequence-number bookkeeping for profile streams: drops, duplicates, reordering, restarts.

/// What one sequence number says about the stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeqEvent {
    /// The first number seen (or the first after [`SequenceTracker::reset`]).
    First,
    /// Exactly one after the previous.
    InOrder,
    /// `missing` numbers were skipped: `first_missing ..= first_missing + missing - 1` (wrapping).
    Gap { first_missing: u32, missing: u32 },
    /// The same number as the previous.
    Duplicate,
    /// Older than the newest seen, within the reorder window: a late frame. It does not move
    /// the newest-seen mark, and is not subtracted from the drop count (we keep no record of
    /// which numbers were missing).
    Late { behind: u32 },
    /// Jumped backwards by more than the reorder window: taken as a sensor restart; the tracker
    /// re-anchors on the new number.
    Restart { previous: u32 },
}

/// Totals since creation or [`SequenceTracker::reset`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SeqCounts {
    pub received: u64,
    pub dropped: u64,
    pub duplicates: u64,
    pub late: u64,
    pub restarts: u64,
}

/// Tracks a u32 sequence that increments by one and wraps at 2^32.
///
/// Differences are taken modulo 2^32 (`seq.wrapping_sub(newest)`): a forward step of less than
/// 2^31 is progress (a gap if more than 1), anything else is a step backwards. `u32::MAX -> 0`
/// is therefore an ordinary in-order step.
#[derive(Clone, Debug)]
pub struct SequenceTracker {
    newest: Option<u32>,
    reorder_window: u32,
    counts: SeqCounts,
}

impl Default for SequenceTracker {
    fn default() -> Self {
        Self::new(Self::DEFAULT_REORDER_WINDOW)
    }
}

impl SequenceTracker {
    /// Backward steps up to this many are "late"; beyond, a restart.
    pub const DEFAULT_REORDER_WINDOW: u32 = 64;

    pub fn new(reorder_window: u32) -> Self {
        Self {
            newest: None,
            reorder_window,
            counts: SeqCounts::default(),
        }
    }

    /// Records `seq` and classifies it.
    pub fn observe(&mut self, seq: u32) -> SeqEvent {
        self.counts.received += 1;
        let Some(newest) = self.newest else {
            self.newest = Some(seq);
            return SeqEvent::First;
        };
        let ahead = seq.wrapping_sub(newest);
        let event = if ahead == 0 {
            self.counts.duplicates += 1;
            SeqEvent::Duplicate
        } else if ahead == 1 {
            SeqEvent::InOrder
        } else if ahead < 1 << 31 {
            let missing = ahead - 1;
            self.counts.dropped += u64::from(missing);
            SeqEvent::Gap {
                first_missing: newest.wrapping_add(1),
                missing,
            }
        } else {
            let behind = newest.wrapping_sub(seq);
            if behind <= self.reorder_window {
                self.counts.late += 1;
                return SeqEvent::Late { behind };
            }
            self.counts.restarts += 1;
            SeqEvent::Restart { previous: newest }
        };
        self.newest = Some(seq);
        event
    }

    /// The newest number seen.
    pub fn newest(&self) -> Option<u32> {
        self.newest
    }

    pub fn counts(&self) -> SeqCounts {
        self.counts
    }

    /// Forget everything (e.g. after reconnecting to the sensor).
    pub fn reset(&mut self) {
        self.newest = None;
        self.counts = SeqCounts::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_order_gap_duplicate_late_restart() {
        let mut t = SequenceTracker::new(10);
        assert_eq!(t.observe(100), SeqEvent::First);
        assert_eq!(t.observe(101), SeqEvent::InOrder);
        assert_eq!(
            t.observe(105),
            SeqEvent::Gap {
                first_missing: 102,
                missing: 3
            }
        );
        assert_eq!(t.observe(105), SeqEvent::Duplicate);
        assert_eq!(t.observe(103), SeqEvent::Late { behind: 2 });
        assert_eq!(t.observe(106), SeqEvent::InOrder);
        assert_eq!(t.observe(50), SeqEvent::Restart { previous: 106 });
        assert_eq!(t.observe(51), SeqEvent::InOrder);
        assert_eq!(
            t.counts(),
            SeqCounts {
                received: 8,
                dropped: 3,
                duplicates: 1,
                late: 1,
                restarts: 1
            }
        );
        t.reset();
        assert_eq!(t.observe(7), SeqEvent::First);
    }

    #[test]
    fn wraps_around() {
        let mut t = SequenceTracker::default();
        t.observe(u32::MAX - 1);
        assert_eq!(t.observe(u32::MAX), SeqEvent::InOrder);
        assert_eq!(t.observe(0), SeqEvent::InOrder);
        assert_eq!(
            t.observe(3),
            SeqEvent::Gap {
                first_missing: 1,
                missing: 2
            }
        );
        assert_eq!(t.observe(u32::MAX), SeqEvent::Late { behind: 4 });
        let mut t = SequenceTracker::default();
        t.observe(u32::MAX - 1);
        assert_eq!(
            t.observe(1),
            SeqEvent::Gap {
                first_missing: u32::MAX,
                missing: 2
            }
        );
        assert_eq!(t.counts().dropped, 2);
    }
}
