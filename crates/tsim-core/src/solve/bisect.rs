/// A failed step's error: whether the same step taken in halves may succeed.
pub trait StepFailure {
    /// Whether halving the step is worth trying.
    fn smaller_step_may_help(&self) -> bool;
}

/// Reaches `to` from `from` (fractions of an increment: load or displacement fraction in a
/// static stage, fraction of Δt in a time step) by `step(from, to)`; where a step fails it
/// is split at its midpoint and its halves are taken in order, each split again where it
/// fails, down to `max_cuts` halvings (2^max_cuts sub-steps); the first sub-step that fails
/// with no halving left, or with an error no halving can help ([`StepFailure`]), returns
/// its error. `step` must leave its state as it was when it
/// fails. Returns the sub-steps' reports merged by `merge` in order (first with second,
/// that with the third, ...), and whether any step was cut.
///
/// Iterative: the sub-intervals still to take are kept on a heap stack of at most
/// `max_cuts + 1` entries (the pending right halves), so the depth costs no call stack.
///
/// The fractions stay dyadic for a whole Δt (0, ½, ¼, ...), so a time step's sub-steps
/// are exact halves.
pub fn bisect<R, E: StepFailure>(
    from: f64,
    to: f64,
    max_cuts: u32,
    step: &mut dyn FnMut(f64, f64) -> Result<R, E>,
    merge: &dyn Fn(R, R) -> R,
) -> Result<(R, bool), E> {
    // The common case, a step that converges whole, allocates nothing (a time step must
    // not: tests/allocation.rs).
    let first = match step(from, to) {
        Ok(r) => return Ok((r, false)),
        Err(e) if max_cuts == 0 || !e.smaller_step_may_help() => return Err(e),
        Err(_) => 0.5 * (from + to),
    };
    // Sub-intervals still to take, the next one last, each with the halvings it has left.
    let mut pending = vec![(first, to, max_cuts - 1), (from, first, max_cuts - 1)];
    let mut merged: Option<R> = None;
    while let Some((a, b, cuts)) = pending.pop() {
        match step(a, b) {
            Ok(r) => {
                merged = Some(match merged.take() {
                    Some(m) => merge(m, r),
                    None => r,
                })
            }
            Err(e) if cuts == 0 || !e.smaller_step_may_help() => return Err(e),
            Err(_) => {
                let mid = 0.5 * (a + b);
                pending.push((mid, b, cuts - 1));
                pending.push((a, mid, cuts - 1));
            }
        }
    }
    // The stack empties only after a sub-step succeeded: the last one taken.
    Ok((merged.expect("a sub-step succeeded"), true))
}

#[cfg(test)]
mod tests {
    use super::{bisect, StepFailure};

    // The tests' errors: a failure halving may help.
    impl StepFailure for f64 {
        fn smaller_step_may_help(&self) -> bool {
            true
        }
    }
    impl StepFailure for (f64, f64) {
        fn smaller_step_may_help(&self) -> bool {
            true
        }
    }
    impl StepFailure for () {
        fn smaller_step_may_help(&self) -> bool {
            true
        }
    }

    /// A step's failure: one halving may help (too long), or one it cannot (the
    /// machine's memory).
    #[derive(Debug, PartialEq)]
    enum Failure {
        TooLong,
        Hopeless,
    }
    impl StepFailure for Failure {
        fn smaller_step_may_help(&self) -> bool {
            *self == Failure::TooLong
        }
    }

    /// An error halving cannot help ends the step where it occurs: at once for the whole
    /// step, and at the first half of a step cut once (its second half is not taken).
    #[test]
    fn hopeless_failures_are_not_halved() {
        for (longest, expected) in [(2.0, vec![(0.0, 1.0)]), (0.6, vec![(0.0, 1.0), (0.0, 0.5)])] {
            let mut taken = Vec::new();
            let mut step = |a: f64, b: f64| -> Result<u32, Failure> {
                taken.push((a, b));
                Err(if b - a > longest { Failure::TooLong } else { Failure::Hopeless })
            };
            let result = bisect(0.0, 1.0, 5, &mut step, &|x, y| x + y);
            assert_eq!((result, taken), (Err(Failure::Hopeless), expected));
        }
    }

    /// A step "fails" when it is longer than 0.3: [0, 1] needs two cuts (quarters), and
    /// the sub-steps tile [0, 1] in order.
    #[test]
    fn splits_failing_steps_in_halves() {
        let mut taken = Vec::new();
        let mut step = |a: f64, b: f64| {
            if b - a > 0.3 {
                Err(b - a)
            } else {
                taken.push((a, b));
                Ok(1)
            }
        };
        let (count, cut) = bisect(0.0, 1.0, 2, &mut step, &|x, y| x + y).unwrap();
        assert_eq!((count, cut), (4, true));
        assert_eq!(taken, vec![(0.0, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.0)]);
        // One cut is not enough: the error of the first half that cannot be cut again.
        assert_eq!(
            bisect(0.0, 1.0, 1, &mut |a, b| if b - a > 0.3 { Err(b - a) } else { Ok(1) }, &|x, y| x + y),
            Err(0.5)
        );
        assert_eq!(bisect(0.0, 0.2, 0, &mut |_, _| Ok::<_, ()>(7), &|x, y| x + y), Ok((7, false)));
    }

    /// A step that succeeds only when short (≤ 2^-depth) or away from 0: [0, 1] is cut
    /// `depth` times down to [0, 2^-depth], then taken back up in doubling steps,
    /// `depth + 1` sub-steps tiling [0, 1] in order. At 40 cuts (more than validation
    /// allows) and at 1000 (near the last halving an f64 interval at 0 has), on a thread
    /// with a 64 KiB stack: the depth costs no call stack.
    #[test]
    fn deep_cuts_take_no_call_stack() {
        for depth in [40_u32, 1000] {
            let run = move || {
                let tiny = 0.5_f64.powi(depth as i32);
                let mut taken = Vec::new();
                let mut step = |a: f64, b: f64| {
                    if b - a > tiny && a == 0.0 {
                        Err((a, b))
                    } else {
                        taken.push((a, b));
                        Ok(1_u64)
                    }
                };
                let (count, cut) = bisect(0.0, 1.0, depth, &mut step, &|x, y| x + y).unwrap();
                assert_eq!((count, cut), (u64::from(depth) + 1, true));
                assert_eq!(taken[0], (0.0, tiny));
                assert!(taken.windows(2).all(|w| w[0].1 == w[1].0 && w[1].1 == 2.0 * w[1].0));
                assert_eq!(taken.last(), Some(&(0.5, 1.0)));
                // One halving fewer than needed: the error of [0, 2^-(depth-1)].
                let short = bisect(
                    0.0,
                    1.0,
                    depth - 1,
                    &mut |a, b| if b - a > tiny && a == 0.0 { Err((a, b)) } else { Ok(1) },
                    &|x, y| x + y,
                );
                assert_eq!(short, Err((0.0, 2.0 * tiny)));
            };
            std::thread::Builder::new()
                .stack_size(64 * 1024)
                .spawn(run)
                .unwrap()
                .join()
                .unwrap();
        }
    }
}
