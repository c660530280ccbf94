//! Exponential back-off for a cheap path that may fail: after a failure the next 2^k
//! chances go to the sure path (k = 0, 1, … up to [`MAX_SKIPS`] chances), and a success
//! resets k. Used where trying costs little when it works and a wasted attempt when it
//! does not, and whether it works depends on the problem: a held factorization at a time
//! step's start (`newton.rs`), Cholesky before LDLᵀ on a sparse symmetric matrix
//! (`linear.rs`). Which path is taken changes the cost only, never the answer.

/// The longest run of skipped attempts between two tries: a probe every 32 chances costs
/// at most 1/32 of a failed attempt per chance.
const MAX_SKIPS: u32 = 32;

#[derive(Clone, Copy, Debug, Default)]
pub struct Backoff {
    /// Chances left to skip before the cheap path is tried again.
    skip: u32,
    /// Chances to skip after the next failure (0: one).
    next: u32,
}

impl Backoff {
    /// Whether to try the cheap path at this chance (counts a skipped one).
    pub fn attempt(&mut self) -> bool {
        if self.skip == 0 {
            return true;
        }
        self.skip -= 1;
        false
    }

    /// The outcome of an attempt.
    pub fn record(&mut self, worked: bool) {
        if worked {
            self.next = 1;
        } else {
            self.skip = self.next.max(1);
            self.next = (2 * self.skip).min(MAX_SKIPS);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Failures double the skipped run up to the cap; a success resets it.
    #[test]
    fn failures_double_the_skips_and_a_success_resets_them() {
        let mut b = Backoff::default();
        let skipped = |b: &mut Backoff| (0..100).take_while(|_| !b.attempt()).count();
        assert_eq!(skipped(&mut b), 0);
        let mut runs = Vec::new();
        for _ in 0..7 {
            b.record(false);
            runs.push(skipped(&mut b));
        }
        assert_eq!(runs, [1, 2, 4, 8, 16, 32, 32]);
        b.record(true);
        assert_eq!(skipped(&mut b), 0);
        b.record(false);
        assert_eq!(skipped(&mut b), 1);
    }
}
