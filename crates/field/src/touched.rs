//! Which blocks of a gradient buffer a backward pass wrote to.
//!
//! Training sums each chunk's gradient buffer into one (a deterministic reduction) and
//! clears it for the next iteration. On a field whose rays meet few texels (a scene mostly
//! empty space, a scheduled occupancy grid), nearly all of each chunk's plane gradients stay
//! zero, and reading and clearing them all was a third of an iteration. The backward pass
//! marks the blocks it writes plane gradients to; the reduction reads only the marked blocks
//! (and the blocks of everything else, lines and networks, which every iteration touches).
//!
//! Skipping a block that holds only zeros changes no sum: a chunk buffer starts at +0 and
//! only ever has values added to it, so it never holds -0, and `x + 0.0 == x` bit for bit.

/// Flags over the blocks of one gradient buffer; tracking is off (every `mark` a no-op)
/// until [`TouchedBlocks::track`] sizes it.
#[derive(Debug, Default, Clone)]
pub struct TouchedBlocks {
    /// log2 of the block length, in floats.
    shift: u32,
    /// One flag per block; empty while tracking is off.
    flags: Vec<bool>,
}

impl TouchedBlocks {
    /// Track a buffer of `len` floats in blocks of `block` floats (a power of two), all
    /// blocks unmarked; a tracker of that size already is kept as it is.
    pub fn track(&mut self, len: usize, block: usize) {
        assert!(block.is_power_of_two(), "block length {block} is not a power of two");
        let shift = block.trailing_zeros();
        let blocks = len.div_ceil(block);
        if self.shift != shift || self.flags.len() != blocks {
            self.shift = shift;
            self.flags = vec![false; blocks];
        }
    }

    /// Whether [`TouchedBlocks::track`] turned tracking on.
    pub fn is_tracking(&self) -> bool {
        !self.flags.is_empty()
    }

    /// Mark the blocks that floats `start..start + len` lie in.
    #[inline]
    pub fn mark(&mut self, start: usize, len: usize) {
        if self.flags.is_empty() || len == 0 {
            return;
        }
        let (a, b) = (start >> self.shift, (start + len - 1) >> self.shift);
        for f in &mut self.flags[a..=b] {
            *f = true;
        }
    }

    /// The flags, one per block.
    pub fn flags(&self) -> &[bool] {
        &self.flags
    }

    /// Unmark every block.
    pub fn clear(&mut self) {
        self.flags.fill(false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_every_block_a_range_meets() {
        let mut t = TouchedBlocks::default();
        t.mark(0, 10);
        assert!(!t.is_tracking(), "untracked marks are no-ops");
        t.track(100, 16);
        assert_eq!(t.flags().len(), 7);
        t.mark(15, 2);
        t.mark(64, 16);
        t.mark(99, 1);
        t.mark(40, 0);
        let marked: Vec<usize> = (0..7).filter(|&k| t.flags()[k]).collect();
        assert_eq!(marked, vec![0, 1, 4, 6]);
        t.clear();
        assert!(t.flags().iter().all(|f| !f));
    }
}
