//! The hot loop allocates nothing: once a time-stepping stage is under way, a Newmark step
//! (Newton iterations, assembly, factorization, solves, the frame handed to the recorders)
//! makes no heap allocation, with the dense and with the sparse solver.
//!
//! A counting global allocator (this test binary only) counts the allocations of the
//! current thread; a recorder notes the count at every frame, so the count between two
//! frames is what one step allocated.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use tsim::config::{parse_case, GroundMotionSpec, NodalForceSpec, TimeFunctionSpec, TimeStep};
use tsim::pipeline::run_case;
use tsim::record::{Constraints, Frame, RecordResult, Recorder, Stage};
use tsim::solve::LinearSolverChoice;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    // try_with: a thread's allocations during its TLS teardown are not counted.
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The allocation count at every deployment frame (storage reserved up front).
struct StepAllocations {
    stage: Option<Stage>,
    counts: Vec<u64>,
}

impl Recorder for StepAllocations {
    fn begin_stage(&mut self, stage: &Stage, _constraints: &Constraints) -> RecordResult {
        self.stage = Some(stage.clone());
        Ok(())
    }
    fn frame(&mut self, _frame: &Frame) -> RecordResult {
        if self.stage.as_ref().is_some_and(|s| s.name() == "deployment") {
            assert!(self.counts.len() < self.counts.capacity(), "reserve more frames");
            self.counts.push(allocations());
        }
        Ok(())
    }
}

/// Allocations of each deployment step of the paper case (0.3 s at Δt = 1 ms) with
/// `solver`; with `loaded`, also a harmonic nodal load, a table load and a ground
/// acceleration table (issue 14's time functions); with `tension_only`, its cords
/// tension-only (slack, held and snapping in the launch: tests/slack.rs).
fn step_allocations(solver: LinearSolverChoice, loaded: bool, tension_only: bool) -> Vec<u64> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/paper.yaml");
    let mut text = std::fs::read_to_string(path).unwrap();
    if tension_only {
        text = text.replacen("      ogden:\n", "      ogden:\n        tension_only: true\n", 1);
    }
    let mut cfg = parse_case(&text, path).unwrap();
    cfg.free_vibration = None;
    let deployment = cfg.deployment.as_mut().unwrap();
    // 300 steps of 1 ms: the launch (0.05 s) covers the first 50, whatever paper.yaml's Δt.
    (deployment.duration, deployment.dt) = (0.3, TimeStep::Fixed(0.001));
    if loaded {
        let table = TimeFunctionSpec::table(vec![[0.0, 0.0], [0.1, 1.0], [0.2, -1.0], [0.25, 0.0]]);
        let force = |force, time| NodalForceSpec {
            nodes: vec![],
            groups: vec!["top".into()],
            force,
            time,
        };
        let harmonic = TimeFunctionSpec::Harmonic {
            frequency: 5.0,
            phase: 0.0,
            duration: None,
        };
        deployment.loads = vec![force([10.0, 0.0, 0.0], harmonic), force([0.0, 5.0, 0.0], table.clone())];
        deployment.ground_motion = Some(GroundMotionSpec {
            acceleration: [0.5, 0.0, 0.2],
            time: table,
        });
    }
    cfg.newton.linear_solver = solver;
    let mut rec = StepAllocations {
        stage: None,
        counts: Vec::with_capacity(1000),
    };
    run_case(&cfg, &mut rec).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(rec.counts.len(), 301, "one frame per step and the initial state");
    rec.counts.windows(2).map(|w| w[1] - w[0]).collect()
}

/// After the first step (which fills the sparse solver's cached element slots and may
/// take the solver's first factorization), no step allocates, but for one: the sparse
/// solver sets up its LU on first need (its symbolic analysis and storage), and with
/// objective damping that is the first step whose Jacobian's skew part is too large for
/// Cholesky on its symmetric part, not necessarily the first step. The launch load acts
/// during the first 50 steps and then stops, so both regimes are covered; a run with time
/// functions and ground motion (dense solver: the load evaluation is solver-independent)
/// allocates nothing either, nor one with tension-only cords.
#[test]
fn newmark_steps_do_not_allocate() {
    for (solver, loaded, tension_only) in [
        (LinearSolverChoice::Dense, false, false),
        (LinearSolverChoice::Sparse, false, false),
        (LinearSolverChoice::Dense, true, false),
        (LinearSolverChoice::Dense, false, true),
    ] {
        let per_step = step_allocations(solver, loaded, tension_only);
        let allocating: Vec<(usize, u64)> = per_step
            .iter()
            .enumerate()
            .skip(1)
            .filter(|&(_, &n)| n > 0)
            .map(|(i, &n)| (i + 1, n))
            .collect();
        eprintln!(
            "{solver:?} (loaded: {loaded}, tension-only: {tension_only}): first step {} allocations, later steps {allocating:?}",
            per_step[0]
        );
        let lu_setup = usize::from(solver == LinearSolverChoice::Sparse);
        assert!(
            allocating.len() <= lu_setup,
            "{solver:?} (loaded: {loaded}): (step, allocations) {allocating:?}"
        );
    }
}
