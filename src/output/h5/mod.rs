//! `result.h5`: every stage of a case in one HDF5 file laid out as netCDF-4, so that
//! `xarray.open_dataset(path, engine="h5netcdf", group=...)` shows named dimensions and
//! coordinates with no glue code (issue 4 is the contract; its names must not change).
//!
//! Layout: root attributes `tsim_version`, `case_id`, `config`, `units`, `status` (and
//! a sweep case's parameters, `sweep.<axis>` and `set.<dotted path>`); groups
//! `/model`, `/formfinding`, `/eigen` (written once, exact sizes) and `/free_vibration`,
//! `/folding`, `/deployment` (unlimited `time` dimension, streamed). Every dimension is an
//! HDF5 dimension scale (H5DS) whose coordinate variable lives in the same group, so each
//! group opens on its own; every variable carries `units` and `long_name`.
//!
//! Streaming and SWMR: the time-stepping groups and all their datasets are created in
//! [`Recorder::model`], because nothing may be created once SWMR writing has started. SWMR
//! starts at the first [`Recorder::begin_stage`], after the static groups are written, so a
//! run that skips form-finding or eigen analysis simply has no such group; time-stepping
//! groups always exist, with `time` of length 0 if the stage did not run. Frames are buffered
//! one chunk's worth of steps at a time (memory bounded whatever the step count) and written
//! and flushed at chunk boundaries and at the end of each stage, which is what a SWMR reader
//! sees grow.

mod contacts;
pub(in crate::output) mod netcdf;
mod series;
#[cfg(test)]
pub(super) mod tests;

use crate::model::AXES;
use crate::record::{
    Constraints, EigenRecord, FormFindRecord, Frame, ModelRecord, Outcome, RecordResult, Recorder, Rigidity, RigidityRecord, Stage,
    StageKind,
};
use hdf5::types::FixedUnicode;
use hdf5::{File, Group};
use netcdf::flat;
use netcdf::untimed_group;
pub(super) use netcdf::{str_attr, untimed_file, varlen, Dims};
use series::{Ids, Series};
use std::path::Path;

type Error = Box<dyn std::error::Error + Send + Sync>;

/// A sweep parameter's value as a root attribute of `result.h5`.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    Number(f64),
    /// A list of numbers (e.g. `eigen.rayleigh.ratios`).
    Numbers(Vec<f64>),
    /// Text, and any other value as its JSON text.
    Text(String),
}

/// Capacity of the fixed-length `status` attribute [bytes]; longer reasons are truncated.
const STATUS_LEN: usize = 512;
/// Target size of one chunk of `position` [bytes]: bounds the buffered block and keeps a
/// chunk within HDF5's default 1 MiB chunk cache.
const CHUNK_BYTES: usize = 1 << 20;
/// Most steps in one chunk (and so between two SWMR flushes).
const CHUNK_STEPS: usize = 256;
/// gzip level: node positions of a moving structure compress about 1.5× at any level, so
/// the fastest is used (level 4 made the paper case's file only 2 % smaller). The chunks
/// are shuffled and deflated by [`ChunkEncoder`], not by HDF5 (see `output/chunk.rs`: the
/// byte planes that do not shrink are stored, within the same deflate stream).
pub(super) const GZIP_LEVEL: u8 = 1;

pub(super) const PAIR: &str = "member of a strut pair: 0 = the lower member index, 1 = the higher";
pub(super) const MIN_CLEARANCE: &str = "smallest surface clearance of non-adjacent struts (axis distance less both radii; <= 0: touching)";
pub(super) const MIN_CLEARANCE_PAIR: &str = "0-based member indices of the struts with the smallest clearance (NaN: no such pair)";

/// Streams a case to HDF5.
///
/// A killed process never leaves a file that reads as complete: the root attribute `status`
/// is created as "running" (and flushed) before any result is written, and only
/// [`Recorder::finish`] overwrites it, with "complete" or "failed: <reason>". A recorder
/// dropped without `finish` (an unwinding panic) writes "failed: recorder dropped before
/// finish". After `kill -9` the status stays "running" and the file keeps every step flushed
/// so far (open it after `h5clear -s`, which clears the SWMR-writer mark). `status` is a
/// fixed-length string created before SWMR starts, since SWMR allows overwriting an
/// attribute in place but not creating one (nor starting while an attribute is open, so it
/// is reopened for each write).
pub struct Hdf5Recorder {
    /// `None` once finished: the file is closed at `finish`.
    open: Option<Open>,
}

struct Open {
    file: File,
    node_ids: Vec<String>,
    member_ids: Vec<String>,
    /// The stepped stages' groups, created by `model`.
    series: Vec<(Stage, Series)>,
    current: Option<usize>,
    swmr: bool,
    /// Eigen stages still to record: their groups are created when they run, which SWMR
    /// forbids, so SWMR waits for the last of them.
    eigen_pending: usize,
}

impl Hdf5Recorder {
    /// Creates (truncates) `path` and marks it "running". Every frame given is recorded: the
    /// output stride (`outputs.every`) is applied by the stages, which call `frame` only for
    /// the steps to record.
    pub fn create(path: &Path, case_id: &str, config_yaml: &str) -> Result<Self, Error> {
        let file = untimed_file().with_fapl(|p| p.libver_v110()).create(path)?;
        str_attr(&file, "tsim_version", env!("CARGO_PKG_VERSION"))?;
        str_attr(&file, "case_id", case_id)?;
        str_attr(&file, "config", config_yaml)?;
        str_attr(&file, "units", "SI (m, N, kg, s)")?;
        file.new_attr::<FixedUnicode<STATUS_LEN>>().create("status")?;
        let open = Open {
            file,
            node_ids: Vec::new(),
            member_ids: Vec::new(),
            series: Vec::new(),
            current: None,
            swmr: false,
            eigen_pending: 0,
        };
        open.set_status("running")?;
        Ok(Hdf5Recorder { open: Some(open) })
    }

    /// The case's sweep parameters as root attributes (before anything streams): numbers
    /// as numbers (a list of numbers as an array), text as text.
    pub fn write_params(&mut self, params: &[(String, ParamValue)]) -> Result<(), Error> {
        let Some(open) = &self.open else { return Ok(()) };
        for (name, value) in params {
            match value {
                ParamValue::Number(x) => open.file.new_attr::<f64>().create(name.as_str())?.write_scalar(x)?,
                ParamValue::Numbers(x) => {
                    open.file.new_attr_builder().with_data(x.as_slice()).create(name.as_str())?;
                }
                ParamValue::Text(t) => str_attr(&open.file, name, t)?,
            }
        }
        Ok(())
    }

    fn open(&mut self) -> Result<&mut Open, Error> {
        self.open.as_mut().ok_or_else(|| "HDF5 recorder already finished".into())
    }
}

impl Open {
    fn set_status(&self, status: &str) -> Result<(), Error> {
        let mut end = status.len().min(STATUS_LEN);
        while !status.is_char_boundary(end) {
            end -= 1;
        }
        self.file
            .attr("status")?
            .write_scalar(&status[..end].parse::<FixedUnicode<STATUS_LEN>>()?)?;
        Ok(self.file.flush()?)
    }

    /// Static groups may only be created before SWMR starts (at the first time-stepping stage).
    fn static_group(&self, name: &str) -> Result<Group, Error> {
        if self.swmr {
            return Err(format!("HDF5: /{name} recorded after a time-stepping stage began").into());
        }
        untimed_group(&self.file, name)
    }

    fn series(&mut self) -> Result<&mut Series, Error> {
        let i = self.current.ok_or("HDF5: frame outside a time-stepping stage")?;
        Ok(&mut self.series[i].1)
    }

    /// Writes the partial block and flushes.
    fn close_stage(&mut self) -> Result<(), Error> {
        self.series()?.write_block()?;
        self.current = None;
        Ok(self.file.flush()?)
    }
}

impl Recorder for Hdf5Recorder {
    fn model(&mut self, record: &ModelRecord) -> RecordResult {
        let open = self.open()?;
        let model = record.model;
        open.node_ids = model.nodes.iter().map(|n| n.id.clone()).collect();
        open.member_ids = model.members.iter().map(|m| m.id.clone()).collect();
        let mut g = Dims::new(open.static_group("model")?);
        g.labels("node", &open.node_ids, "node id")?;
        g.labels("member", &open.member_ids, "member id")?;
        g.labels("xyz", &AXES, "coordinate axis")?;
        g.coord("end", &[0i64, 1], "1", "member end (0 = first node, 1 = second)")?;
        let xyz: Vec<f64> = model.nodes.iter().flat_map(|n| n.xyz.iter().copied()).collect();
        g.var("initial_position", &["node", "xyz"], &xyz, "m", "initial node position")?;
        let ends: Vec<i64> = model.members.iter().flat_map(|m| m.nodes.map(|n| n as i64)).collect();
        g.var(
            "member_nodes",
            &["member", "end"],
            &ends,
            "1",
            "0-based index of the member's end nodes",
        )?;
        let kinds: Vec<&str> = model.members.iter().map(|m| m.kind.as_str()).collect();
        g.var("member_kind", &["member"], &varlen(&kinds)?, "1", "member kind (strut or cable)")?;
        g.var("rest_length", &["member"], record.rest_lengths, "m", "real-material rest length")?;
        g.var("mass", &["node"], record.masses, "kg", "lumped nodal mass")?;
        let mass = g.group.dataset("mass")?;
        str_attr(&mass, "mass_reading", record.mass_reading)?;
        let support: Vec<u8> = model.nodes.iter().flat_map(|n| n.support.map(u8::from)).collect();
        g.var("support", &["node", "xyz"], &support, "1", "supported direction (1 = fixed)")?;
        let mut node_groups = vec![Vec::new(); model.node_count()];
        for (name, nodes) in &model.node_groups {
            nodes.iter().for_each(|&n| node_groups[n].push(name.as_str()));
        }
        let node_groups: Vec<String> = node_groups.iter().map(|g| g.join(",")).collect();
        g.var("node_group", &["node"], &varlen(&node_groups)?, "1", "node groups, comma-separated")?;
        let member_groups: Vec<String> = model.members.iter().map(|m| m.groups.join(",")).collect();
        g.var(
            "member_group",
            &["member"],
            &varlen(&member_groups)?,
            "1",
            "member groups, comma-separated",
        )?;

        let chunk = (CHUNK_BYTES / (24 * model.node_count().max(1))).clamp(1, CHUNK_STEPS);
        for layout in record.stages.iter().filter(|l| l.stage.kind.is_stepped()) {
            let ids = Ids {
                nodes: &open.node_ids,
                members: &open.member_ids,
            };
            let group = untimed_group(&open.file, layout.stage.name())?;
            str_attr(&group, "stage_kind", layout.stage.kind.name())?;
            let series = Series::create(group, layout, ids, record, chunk)?;
            open.series.push((layout.stage.clone(), series));
        }
        open.eigen_pending = record.stages.iter().filter(|l| l.stage.kind == StageKind::Eigen).count();
        Ok(open.file.flush()?)
    }

    fn formfinding(&mut self, record: &FormFindRecord) -> RecordResult {
        let open = self.open()?;
        let mut g = Dims::new(open.static_group(record.stage.name())?);
        let iterations: Vec<i64> = (0..record.residuals.len() as i64).collect();
        g.coord("iteration", &iterations, "1", "Newton iteration")?;
        g.labels("node", &open.node_ids, "node id")?;
        g.labels("member", &open.member_ids, "member id")?;
        g.labels("xyz", &AXES, "coordinate axis")?;
        g.var(
            "residual_norm",
            &["iteration"],
            record.residuals,
            "N",
            "norm of the unbalanced force",
        )?;
        g.var(
            "position",
            &["node", "xyz"],
            &flat(record.positions),
            "m",
            "equilibrium node position",
        )?;
        g.var(
            "member_force",
            &["member"],
            record.forces,
            "N",
            "equilibrium member force (tension > 0)",
        )?;
        if let Some(c) = record.clearance {
            let nearest = c
                .nearest
                .map_or((f64::NAN, [f64::NAN; 2]), |n| (n.clearance, n.members.map(|m| m as f64)));
            g.coord("pair", &[0i64, 1], "1", PAIR)?;
            g.var("min_clearance", &[], &[nearest.0], "m", MIN_CLEARANCE)?;
            g.var("min_clearance_pair", &["pair"], &nearest.1, "1", MIN_CLEARANCE_PAIR)?;
        }
        Ok(open.file.flush()?)
    }

    fn rigidity(&mut self, record: &RigidityRecord) -> RecordResult {
        let open = self.open()?;
        let g = open.static_group("structure_analysis")?;
        match record.analysis {
            Ok(r) => write_rigidity(Dims::new(g), r, &open.node_ids, &open.member_ids)?,
            Err(reason) => str_attr(&g, "skipped", reason)?,
        }
        Ok(open.file.flush()?)
    }

    fn eigen(&mut self, record: &EigenRecord) -> RecordResult {
        let open = self.open()?;
        let mut g = Dims::new(open.static_group(record.stage.name())?);
        open.eigen_pending = open.eigen_pending.saturating_sub(1);
        str_attr(&g.group, "stage_kind", record.stage.kind.name())?;
        let modes: Vec<i64> = (1..=record.omega2.len() as i64).collect();
        g.coord("mode", &modes, "1", "mode number (1-based, ascending frequency)")?;
        g.labels("node", &open.node_ids, "node id")?;
        g.labels("xyz", &AXES, "coordinate axis")?;
        g.var("omega2", &["mode"], record.omega2, "rad2 s-2", "squared angular eigenfrequency")?;
        let freq: Vec<f64> = record.omega2.iter().map(|w2| w2.max(0.0).sqrt() / std::f64::consts::TAU).collect();
        g.var("frequency", &["mode"], &freq, "Hz", "eigenfrequency")?;
        let shapes: Vec<f64> = record.mode_shapes.iter().flat_map(|s| flat(s)).collect();
        g.var(
            "mode_shape",
            &["mode", "node", "xyz"],
            &shapes,
            "m kg-1/2",
            "mass-normalised mode shape",
        )?;
        g.group
            .new_attr::<f64>()
            .create("rayleigh_alpha")?
            .write_scalar(&record.rayleigh_alpha)?;
        g.group
            .new_attr::<f64>()
            .create("rayleigh_beta")?
            .write_scalar(&record.rayleigh_beta)?;
        let damping_modes: Vec<i64> = record.damping_modes.iter().map(|&m| m as i64).collect();
        g.group.new_attr_builder().with_data(&damping_modes).create("damping_modes")?;
        g.group.new_attr_builder().with_data(record.damping_ratio).create("damping_ratio")?;
        Ok(open.file.flush()?)
    }

    fn begin_stage(&mut self, stage: &Stage, constraints: &Constraints) -> RecordResult {
        let open = self.open()?;
        let i = open
            .series
            .iter()
            .position(|(s, _)| s == stage)
            .ok_or_else(|| format!("HDF5: {} is not a time-stepping stage (or model() was not recorded)", stage.name()))?;
        if open.series[i].1.constraints != *constraints {
            return Err(format!(
                "HDF5: {} constrains other directions than model() declared: its `support` dimension was fixed then",
                stage.name()
            )
            .into());
        }
        // Groups cannot be created once SWMR has started: it starts at the first dynamic
        // or folding stage after the last eigen stage (static stages are short; readers
        // follow the long stages).
        if !open.swmr && open.eigen_pending == 0 && stage.kind != StageKind::Static {
            open.file.start_swmr()?;
            open.swmr = true;
        }
        open.current = Some(i);
        Ok(())
    }

    fn frame(&mut self, frame: &Frame) -> RecordResult {
        let open = self.open()?;
        if open.series()?.push(frame)? {
            open.file.flush()?;
        }
        Ok(())
    }

    fn end_stage(&mut self, _stage: &Stage) -> RecordResult {
        self.open()?.close_stage()
    }

    /// The status is set even when the last block cannot be written (a full disk): the
    /// file then reads "failed", never "running", and the block's error is returned.
    fn finish(&mut self, outcome: &Outcome) -> RecordResult {
        let mut open = self.open.take().ok_or("HDF5 recorder already finished")?;
        let closed = if open.current.is_some() { open.close_stage() } else { Ok(()) };
        let set = open.set_status(&outcome.unless_recording_failed(&closed).to_string());
        closed.and(set)
    }
}

impl Drop for Hdf5Recorder {
    fn drop(&mut self) {
        if self.open.is_some() {
            let _ = self.finish(&Outcome::Failed("recorder dropped before finish".into()));
        }
    }
}

/// `/structure_analysis`: the counts and verdicts as attributes, the singular values, the
/// self-stress basis and the proper self-stress (member forces, unit-free), the internal
/// mechanisms (free DOF, unit-free) and their prestress stiffness.
fn write_rigidity(mut g: Dims, r: &Rigidity, node_ids: &[String], member_ids: &[String]) -> Result<(), Error> {
    let count = |name: &str, v: usize| g.group.new_attr::<i64>().create(name)?.write_scalar(&(v as i64));
    count("rank", r.rank)?;
    count("s", r.s)?;
    count("m", r.m)?;
    count("rigid_body_modes", r.rigid_body_modes)?;
    count("m_internal", r.internal_mechanisms())?;
    count("prestress_stable", usize::from(r.stability.prestress_stable))?;
    count("super_stable", usize::from(r.stability.super_stable))?;
    let real = |name: &str, v: f64| g.group.new_attr::<f64>().create(name)?.write_scalar(&v);
    real("rank_tolerance", r.tolerance)?;
    real("prestress_residual", r.prestress_residual)?;
    real("stiffness_tolerance", r.stability.tolerance)?;
    str_attr(&g.group, "self_stress_source", &r.self_stress_source)?;
    str_attr(&g.group, "super_stability", &r.stability.super_stability)?;
    let index = |n: usize| (1..=n as i64).collect::<Vec<_>>();
    g.labels("member", member_ids, "member id")?;
    let dofs: Vec<String> = r.dofs.iter().map(|&(n, a)| format!("{}.{}", node_ids[n], AXES[a])).collect();
    g.labels("dof", &dofs, "free degree of freedom (node.axis)")?;
    g.coord(
        "singular",
        &index(r.singular_values.len()),
        "1",
        "singular value number (descending)",
    )?;
    g.coord("state", &index(r.s), "1", "self-stress state number")?;
    g.coord(
        "mode",
        &index(r.mechanisms.ncols()),
        "1",
        "internal mechanism number (ascending prestress stiffness)",
    )?;
    g.var(
        "singular_value",
        &["singular"],
        &r.singular_values,
        "1",
        "singular value of the equilibrium matrix",
    )?;
    let rows = |m: &faer::Mat<f64>| -> Vec<f64> { (0..m.nrows()).flat_map(|i| (0..m.ncols()).map(move |j| m[(i, j)])).collect() };
    g.var(
        "self_stress",
        &["member", "state"],
        &rows(&r.self_stress),
        "1",
        "orthonormal self-stress basis (member forces)",
    )?;
    if let Some(t) = &r.proper_self_stress {
        g.var(
            "proper_self_stress",
            &["member"],
            t,
            "1",
            "self-stress with struts compressed and cables tensioned, max |t| = 1",
        )?;
    }
    g.var(
        "mechanism",
        &["dof", "mode"],
        &rows(&r.mechanisms),
        "1",
        "orthonormal internal mechanism basis",
    )?;
    g.var(
        "mechanism_stiffness",
        &["mode"],
        &r.stability.mechanism_stiffness,
        "N m-1",
        "prestress stiffness of the mechanism (eigenvalue of the geometric stiffness on the mechanisms)",
    )
}
