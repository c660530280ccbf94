/// Reaches `to` from `from` (fractions of an increment: load or displacement fraction in a
/// static stage, fraction of Δt in a time step) by `step(from, to)`; where a step fails it
/// is split at its midpoint, recursively up to `max_cuts` deep (2^max_cuts sub-steps), and
/// the first error that cannot be cut further is returned. `step` must leave its state as
/// it was when it fails. Returns the sub-steps' reports merged by `merge`, and whether any
/// step was cut.
///
/// The fractions stay dyadic for a whole Δt (0, ½, ¼, ...), so a time step's sub-steps
/// are exact halves.
pub fn bisect<R, E>(
    from: f64,
    to: f64,
    max_cuts: u32,
    step: &mut dyn FnMut(f64, f64) -> Result<R, E>,
    merge: &dyn Fn(R, R) -> R,
) -> Result<(R, bool), E> {
    match step(from, to) {
        Ok(r) => Ok((r, false)),
        Err(e) if max_cuts == 0 => Err(e),
        Err(_) => {
            let mid = 0.5 * (from + to);
            let (first, _) = bisect(from, mid, max_cuts - 1, step, merge)?;
            let (second, _) = bisect(mid, to, max_cuts - 1, step, merge)?;
            Ok((merge(first, second), true))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::bisect;

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
}
