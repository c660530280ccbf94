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

use super::chunk::ChunkEncoder;
use crate::model::AXES;
use crate::record::{
    ClearanceEvent, Constraints, EigenRecord, EventKind, FormFindRecord, Frame, ModelRecord, Outcome, RecordResult, Recorder, Rigidity,
    RigidityRecord, Stage, StageKind, StageLayout,
};
use hdf5::types::{FixedUnicode, VarLenUnicode};
use hdf5::{Dataset, File, Group, H5Type, Location};
use hdf5_sys::h5::{herr_t, hsize_t};
use hdf5_sys::h5d::H5Dwrite;
use hdf5_sys::h5i::hid_t;
use hdf5_sys::h5p::{H5Pclose, H5Pcreate, H5Pset_buffer, H5P_CLS_DATASET_XFER};
use hdf5_sys::h5s::H5S_ALL;
use nalgebra::Vector3;
use std::ffi::{c_char, c_uint, CString};
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
const GZIP_LEVEL: u8 = 1;

// The high-level dimension-scale API (libhdf5_hl, linked by hdf5-sys's `hl` feature), which
// neither hdf5-metno nor its -sys crate binds.
extern "C" {
    fn H5DSset_scale(dsid: hid_t, dimname: *const c_char) -> herr_t;
    fn H5DSattach_scale(did: hid_t, dsid: hid_t, idx: c_uint) -> herr_t;
}

/// Rows per chunk of a clearance event table (events are rare; a chunk is 0.5–1 KiB).
const EVENT_CHUNK: usize = 64;
const PAIR: &str = "member of a strut pair: 0 = the lower member index, 1 = the higher";
const MIN_CLEARANCE: &str = "smallest surface clearance of non-adjacent struts (axis distance less both radii; <= 0: touching)";
const MIN_CLEARANCE_PAIR: &str = "0-based member indices of the struts with the smallest clearance (NaN: no such pair)";

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
        let file = File::with_options().with_fapl(|p| p.libver_v110()).create(path)?;
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
        Ok(self.file.create_group(name)?)
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
            let group = open.file.create_group(layout.stage.name())?;
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

    fn finish(&mut self, outcome: &Outcome) -> RecordResult {
        let mut open = self.open.take().ok_or("HDF5 recorder already finished")?;
        if open.current.is_some() {
            open.close_stage()?;
        }
        open.set_status(&outcome.to_string())
    }
}

impl Drop for Hdf5Recorder {
    fn drop(&mut self) {
        if self.open.is_some() {
            let _ = self.finish(&Outcome::Failed("recorder dropped before finish".into()));
        }
    }
}

/// Node and member ids, the labels of the `node` and `member` dimensions.
#[derive(Clone, Copy)]
struct Ids<'a> {
    nodes: &'a [String],
    members: &'a [String],
}

/// The datasets of one time-stepping stage and the block of steps not yet written.
struct Series {
    /// (dataset, buffered values of its rows not yet written)
    columns: Vec<(Dataset, Vec<f64>)>,
    /// The directions of the `support` dimension (the reactions' order).
    constraints: Constraints,
    folding: bool,
    /// Lowest modes recorded per step (folding with `folding.eigen`; 0: none).
    modes: usize,
    /// Whether the stage changes rest lengths in time (`rest_length`, `actuator_work`).
    actuated: bool,
    events: EventTable,
    written: usize,
    buffered: usize,
    chunk: usize,
    encoder: ChunkEncoder,
}

/// The streamed member forces and lengths, the energies and, in an `actuated` stage, the
/// rest lengths and the actuators' work, in [`Series::push`]'s order.
fn member_and_energy_columns(g: &Dims, actuated: bool, chunk: usize) -> Result<Vec<Dataset>, Error> {
    let mut columns = Vec::new();
    for (name, units, long_name) in [
        ("member_force", "N", "member force (tension > 0)"),
        ("member_length", "m", "member length"),
        ("kinetic_energy", "J", "kinetic energy"),
        ("strain_energy", "J", "strain energy"),
        ("damping_energy", "J", "energy dissipated by damping since the stage began"),
        (
            "external_work",
            "J",
            "work of external loads and prescribed displacements since the stage began",
        ),
    ] {
        let dims: &[&str] = if name.starts_with("member") { &["member"] } else { &[] };
        columns.push(g.streamed(name, dims, chunk, units, long_name)?);
    }
    if actuated {
        columns.push(g.streamed(
            "rest_length",
            &["member"],
            chunk,
            "m",
            "member rest length, changed in time by actuation",
        )?);
        columns.push(g.streamed(
            "actuator_work",
            &[],
            chunk,
            "J",
            "work done on the members by changing their rest lengths since the stage began",
        )?);
    }
    Ok(columns)
}

impl Series {
    /// Column order, used by [`Series::push`]: time, [fraction], position, [velocity],
    /// member_force, member_length, kinetic, strain, damping, external, [rest_length,
    /// actuator_work (a stage in `record.actuated`)], applied_load,
    /// reaction, equilibrium_error, [mode_omega2, lowest_mode], min_clearance,
    /// min_clearance_pair; the clearance events in a table of their own. Folding, a static stage, has `fraction` and no
    /// `velocity`. The `support` dimension (the stage's constrained directions, from
    /// `record`) has the coordinate `support` (labels `<node>.<axis>`) and the auxiliary
    /// coordinates `support_node`, `support_axis` and `support_kind` (`support` or
    /// `prescribed`).
    fn create(group: Group, layout: &StageLayout, ids: Ids, record: &ModelRecord, chunk: usize) -> Result<Self, Error> {
        let (node_ids, member_ids) = (ids.nodes, ids.members);
        let constraints = layout.constraints.clone();
        let folding = layout.stage.is_static();
        let mut g = Dims::new(group);
        let (units, long_name) = if folding {
            ("1", "static step")
        } else {
            ("s", "simulated time since the stage began")
        };
        let time = g.streamed("time", &[], chunk, units, long_name)?;
        g.scale("time", time.clone())?;
        g.labels("node", node_ids, "node id")?;
        g.labels("member", member_ids, "member id")?;
        g.labels("xyz", &AXES, "coordinate axis")?;
        g.labels(
            "support",
            &constraints.labels(record.model),
            "constrained direction (node.axis): a support, or prescribed by the stage",
        )?;
        let support_node: Vec<&str> = constraints.0.iter().map(|c| node_ids[c.node].as_str()).collect();
        g.var(
            "support_node",
            &["support"],
            &varlen(&support_node)?,
            "1",
            "node id of the constrained direction",
        )?;
        let support_axis: Vec<&str> = constraints.0.iter().map(|c| AXES[c.axis]).collect();
        g.var(
            "support_axis",
            &["support"],
            &varlen(&support_axis)?,
            "1",
            "axis of the constrained direction",
        )?;
        let kind: Vec<&str> = constraints
            .0
            .iter()
            .map(|c| if c.prescribed { "prescribed" } else { "support" })
            .collect();
        g.var(
            "support_kind",
            &["support"],
            &varlen(&kind)?,
            "1",
            "support of the model, or direction prescribed by the stage",
        )?;
        let mut columns = vec![time];
        if folding {
            let what = match layout.stage.kind {
                StageKind::Folding => "applied fraction of the prescribed displacement",
                _ => "load factor: applied fraction of the total load (under displacement control: the factor on the `loads` pattern)",
            };
            columns.push(g.streamed("fraction", &[], chunk, "1", what)?);
        }
        columns.push(g.streamed("position", &["node", "xyz"], chunk, "m", "node position")?);
        if !folding {
            columns.push(g.streamed("velocity", &["node", "xyz"], chunk, "m s-1", "node velocity")?);
        }
        let actuated = layout.actuated;
        columns.extend(member_and_energy_columns(&g, actuated, chunk)?);
        for (name, dims, long_name) in [
            (
                "applied_load",
                &["node", "xyz"][..],
                "external load applied on the node (dead load, weight, stage loads)",
            ),
            (
                "reaction",
                &["support"],
                "reaction at the constrained direction (force on the node)",
            ),
            (
                "equilibrium_error",
                &[],
                "norm of sum of reactions and applied loads less inertia and mass-proportional damping",
            ),
        ] {
            columns.push(g.streamed(name, dims, chunk, "N", long_name)?);
        }
        // CF: makes xarray list `fraction` and the support labels as (non-dimension)
        // coordinates.
        let reaction = columns.len() - 2;
        for (k, ds) in columns.iter().enumerate().skip(if folding { 2 } else { 1 }) {
            let support = "support_node support_axis support_kind";
            match (folding, k == reaction) {
                (true, true) => str_attr(ds, "coordinates", &format!("fraction {support}"))?,
                (true, false) => str_attr(ds, "coordinates", "fraction")?,
                (false, true) => str_attr(ds, "coordinates", support)?,
                (false, false) => {}
            }
        }
        let modes = layout.path_modes;
        if modes > 0 {
            let numbers: Vec<i64> = (1..=modes as i64).collect();
            g.coord("mode", &numbers, "1", "mode number, 1 = lowest")?;
            let omega2 = g.streamed(
                "mode_omega2",
                &["mode"],
                chunk,
                "rad2 s-2",
                "lowest eigenvalues ω² of K_T φ = ω² M φ, prescribed directions held",
            )?;
            let lowest = g.streamed(
                "lowest_mode",
                &["node", "xyz"],
                chunk,
                "m kg-1/2",
                "mass-normalised lowest mode (zero at constrained directions)",
            )?;
            for ds in [&omega2, &lowest] {
                str_attr(ds, "coordinates", "fraction")?;
            }
            columns.extend([omega2, lowest]);
        }
        let (clearance, events) = clearance_columns(&mut g, folding, chunk)?;
        columns.extend(clearance);
        let columns = columns.into_iter().map(|ds| (ds, Vec::new())).collect();
        Ok(Series {
            columns,
            constraints,
            folding,
            modes,
            actuated,
            events,
            written: 0,
            buffered: 0,
            chunk,
            encoder: ChunkEncoder::new(GZIP_LEVEL.into()),
        })
    }

    /// Buffers a frame; writes the block when it fills a chunk, and then says so (true): a
    /// SWMR reader sees the new steps only once the caller flushes the file.
    fn push(&mut self, f: &Frame) -> Result<bool, Error> {
        let n = f.positions.len();
        if f.reactions.len() != self.constraints.len() || f.applied.len() != n {
            return Err(format!(
                "HDF5: frame {} has {} reactions and {} applied loads for {} constrained directions and {n} nodes",
                f.step,
                f.reactions.len(),
                f.applied.len(),
                self.constraints.len()
            )
            .into());
        }
        let mut cols = self.columns.iter_mut().map(|(_, buf)| buf);
        let mut next = || cols.next().expect("column layout");
        next().push(if self.folding { f.step as f64 } else { f.time });
        if self.folding {
            next().push(f.time);
        }
        extend_vectors(next(), f.positions);
        if !self.folding {
            match f.velocities {
                Some(v) => extend_vectors(next(), v),
                None => next().extend(std::iter::repeat_n(f64::NAN, 3 * n)),
            }
        }
        next().extend_from_slice(f.forces);
        next().extend_from_slice(f.lengths);
        let e = f.energy;
        for value in [e.kinetic, e.strain, e.damping, e.external] {
            next().push(value);
        }
        if self.actuated {
            let rest = f
                .rest_lengths
                .ok_or_else(|| format!("HDF5: frame {} of an actuated stage lacks its rest lengths", f.step))?;
            next().extend_from_slice(rest);
            next().push(e.actuation);
        }
        extend_vectors(next(), f.applied);
        next().extend_from_slice(f.reactions);
        next().push(f.equilibrium_error);
        if self.modes > 0 {
            let m = f
                .modes
                .filter(|m| m.omega2.len() == self.modes && m.lowest.len() == n)
                .ok_or_else(|| format!("HDF5: frame {} lacks its {} lowest modes", f.step, self.modes))?;
            next().extend_from_slice(m.omega2);
            extend_vectors(next(), m.lowest);
        }
        // NaN when not followed or without a pair: the layout is fixed before streaming.
        let nearest = f.clearance.and_then(|c| c.nearest);
        next().push(nearest.map_or(f64::NAN, |n| n.clearance));
        next().extend(nearest.map_or([f64::NAN; 2], |n| n.members.map(|m| m as f64)));
        if let Some(c) = f.clearance {
            self.events.append(c.events)?;
        }
        self.buffered += 1;
        let full = self.buffered == self.chunk;
        if full {
            self.write_block()?;
        }
        Ok(full)
    }

    /// Appends the buffered steps to every dataset; the caller flushes the file.
    fn write_block(&mut self) -> Result<(), Error> {
        if self.buffered == 0 {
            return Ok(());
        }
        for (ds, buf) in &mut self.columns {
            append_chunk(ds, self.written, self.buffered, self.chunk, buf, &mut self.encoder)?;
            buf.clear();
        }
        self.written += self.buffered;
        self.buffered = 0;
        Ok(())
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

/// The clearance variables of a time-stepping group: `min_clearance (time)` and
/// `min_clearance_pair (time, pair)`, streamed, and the event table.
fn clearance_columns(g: &mut Dims, folding: bool, chunk: usize) -> Result<([Dataset; 2], EventTable), Error> {
    g.coord("pair", &[0i64, 1], "1", PAIR)?;
    let min = g.streamed("min_clearance", &[], chunk, "m", MIN_CLEARANCE)?;
    let pair = g.streamed("min_clearance_pair", &["pair"], chunk, "1", MIN_CLEARANCE_PAIR)?;
    if folding {
        for ds in [&min, &pair] {
            str_attr(ds, "coordinates", "fraction")?;
        }
    }
    Ok(([min, pair], EventTable::create(g, folding)?))
}

/// The clearance events of one stage, a table along the dimension `clearance_event`:
/// `clearance_event_step`, `_time`, `_pair (clearance_event, pair)`, `_kind` (0 touch,
/// 1 pass_through, as CF flags) and `_clearance`. Events are rare: each frame's are
/// written when it arrives, not buffered.
struct EventTable {
    index: Dataset,
    step: Dataset,
    time: Dataset,
    pair: Dataset,
    kind: Dataset,
    clearance: Dataset,
    rows: usize,
}

impl EventTable {
    fn create(g: &mut Dims, folding: bool) -> Result<Self, Error> {
        let index = extendable::<i64>(&g.group, "clearance_event", 1)?;
        describe(&index, "1", "clearance event number")?;
        g.scale("clearance_event", index.clone())?;
        let column = |ds: Dataset, dims: &[&str], units: &str, long_name: &str| -> Result<Dataset, Error> {
            describe(&ds, units, long_name)?;
            g.attach(&ds, dims)?;
            Ok(ds)
        };
        let event = ["clearance_event"];
        let (time_units, time_name) = if folding {
            (
                "1",
                "applied fraction at the event (a pass-through: interpolated between the steps)",
            )
        } else {
            (
                "s",
                "time of the event since the stage began (a pass-through: the interpolated moment of crossing)",
            )
        };
        let step = column(
            extendable::<i64>(&g.group, "clearance_event_step", 1)?,
            &event,
            "1",
            "step at which the event is seen",
        )?;
        let time = column(
            extendable::<f64>(&g.group, "clearance_event_time", 1)?,
            &event,
            time_units,
            time_name,
        )?;
        let pair = column(
            extendable::<i64>(&g.group, "clearance_event_pair", 2)?,
            &["clearance_event", "pair"],
            "1",
            "0-based member indices of the two struts",
        )?;
        let kind = column(extendable::<i8>(&g.group, "clearance_event_kind", 1)?, &event, "1", "kind of event")?;
        kind.new_attr_builder().with_data(&[0i8, 1][..]).create("flag_values")?;
        str_attr(&kind, "flag_meanings", "touch pass_through")?;
        let clearance = column(
            extendable::<f64>(&g.group, "clearance_event_clearance", 1)?,
            &event,
            "m",
            "clearance of the pair at the step of the event",
        )?;
        Ok(EventTable {
            index,
            step,
            time,
            pair,
            kind,
            clearance,
            rows: 0,
        })
    }

    fn append(&mut self, events: &[ClearanceEvent]) -> Result<(), Error> {
        if events.is_empty() {
            return Ok(());
        }
        let (start, end) = (self.rows, self.rows + events.len());
        let index: Vec<i64> = (start as i64..end as i64).collect();
        append_rows(&self.index, start, &index)?;
        append_rows(&self.step, start, &events.iter().map(|e| e.step as i64).collect::<Vec<_>>())?;
        append_rows(&self.time, start, &events.iter().map(|e| e.time).collect::<Vec<_>>())?;
        let kind = |e: &ClearanceEvent| match e.kind {
            EventKind::Touch => 0i8,
            EventKind::PassThrough => 1,
        };
        append_rows(&self.kind, start, &events.iter().map(kind).collect::<Vec<_>>())?;
        append_rows(&self.clearance, start, &events.iter().map(|e| e.clearance).collect::<Vec<_>>())?;
        self.pair.resize(vec![end, 2])?;
        for side in 0..2 {
            let members: Vec<i64> = events.iter().map(|e| e.members[side] as i64).collect();
            self.pair.write_slice(&members, (start..end, side))?;
        }
        self.rows = end;
        Ok(())
    }
}

/// An empty dataset growing along its first axis, `width` values per row (1: a 1-D one).
fn extendable<T: H5Type>(group: &Group, name: &str, width: usize) -> Result<Dataset, Error> {
    let builder = group.new_dataset::<T>();
    let ds = if width == 1 {
        builder
            .chunk(vec![EVENT_CHUNK])
            .shape(vec![hdf5::Extent::resizable(0)])
            .create(name)?
    } else {
        builder
            .chunk(vec![EVENT_CHUNK, width])
            .shape(vec![hdf5::Extent::resizable(0), width.into()])
            .create(name)?
    };
    Ok(ds)
}

/// Appends `values` to the 1-D dataset `ds` of `start` rows.
fn append_rows<T: H5Type>(ds: &Dataset, start: usize, values: &[T]) -> Result<(), Error> {
    ds.resize(vec![start + values.len()])?;
    Ok(ds.write_slice(values, start..start + values.len())?)
}

/// Creates datasets in one group and attaches them to the group's dimension scales.
pub(super) struct Dims {
    pub(super) group: Group,
    scales: Vec<(String, Dataset)>,
}

impl Dims {
    pub(super) fn new(group: Group) -> Self {
        Dims { group, scales: Vec::new() }
    }

    /// A coordinate variable: a 1-D dataset that is the dimension scale of its own name.
    pub(super) fn coord<T: H5Type>(&mut self, name: &str, values: &[T], units: &str, long_name: &str) -> Result<(), Error> {
        let ds = self.group.new_dataset::<T>().shape(values.len()).create(name)?;
        write_whole(&ds, values)?;
        describe(&ds, units, long_name)?;
        self.scale(name, ds)
    }

    pub(super) fn labels<S: AsRef<str>>(&mut self, name: &str, labels: &[S], long_name: &str) -> Result<(), Error> {
        self.coord(name, &varlen(labels)?, "1", long_name)
    }

    /// Makes `ds` the dimension scale `name` of this group.
    fn scale(&mut self, name: &str, ds: Dataset) -> Result<(), Error> {
        let c_name = CString::new(name)?;
        {
            let _lock = hdf5_sys::LOCK.lock();
            // SAFETY: `ds` is an open dataset and `c_name` outlives the call.
            check(unsafe { H5DSset_scale(ds.id(), c_name.as_ptr()) }, "H5DSset_scale")?;
        }
        self.scales.push((name.into(), ds));
        Ok(())
    }

    fn find(&self, dim: &str) -> Result<&Dataset, Error> {
        Ok(&self
            .scales
            .iter()
            .find(|(n, _)| n == dim)
            .ok_or_else(|| format!("HDF5: no dimension {dim}"))?
            .1)
    }

    fn attach(&self, ds: &Dataset, dims: &[&str]) -> Result<(), Error> {
        for (axis, dim) in dims.iter().enumerate() {
            let scale = self.find(dim)?;
            let _lock = hdf5_sys::LOCK.lock();
            // SAFETY: both ids are open datasets of the same file.
            check(unsafe { H5DSattach_scale(ds.id(), scale.id(), axis as c_uint) }, "H5DSattach_scale")?;
        }
        Ok(())
    }

    fn sizes(&self, dims: &[&str]) -> Result<Vec<usize>, Error> {
        dims.iter().map(|d| Ok(self.find(d)?.size())).collect()
    }

    /// A fixed-size variable written at once; `values` in row-major order over `dims`.
    pub(super) fn var<T: H5Type>(&self, name: &str, dims: &[&str], values: &[T], units: &str, long_name: &str) -> Result<(), Error> {
        let ds = self.group.new_dataset::<T>().shape(self.sizes(dims)?).create(name)?;
        write_whole(&ds, values)?;
        describe(&ds, units, long_name)?;
        self.attach(&ds, dims)
    }

    /// A variable over (time, `dims`...) growing along time, chunked `chunk` steps deep, with
    /// shuffle + gzip; attached to the `time` scale once that exists.
    fn streamed(&self, name: &str, dims: &[&str], chunk: usize, units: &str, long_name: &str) -> Result<Dataset, Error> {
        let tail = self.sizes(dims)?;
        let shape: Vec<hdf5::Extent> = std::iter::once(hdf5::Extent::resizable(0))
            .chain(tail.iter().map(|&n| n.into()))
            .collect();
        let chunk_shape: Vec<usize> = std::iter::once(chunk).chain(tail.iter().map(|&n| n.max(1))).collect();
        let ds = self
            .group
            .new_dataset::<f64>()
            .chunk(chunk_shape)
            .shuffle()
            .deflate(GZIP_LEVEL)
            .shape(shape)
            .create(name)?;
        describe(&ds, units, long_name)?;
        if self.find("time").is_ok() {
            self.attach(&ds, &[&["time"], dims].concat())?;
        }
        Ok(ds)
    }
}

/// Extends `ds` along its first axis by `rows` rows (row-major `values`) and stores them as
/// the chunk that starts at row `start`, a multiple of the chunk length `chunk`: every
/// block the writer appends fills one chunk (the last of a stage, partly). The chunk is
/// encoded here and written with `H5Dwrite_chunk`, filter mask 0: both of the dataset's
/// filters applied.
fn append_chunk(ds: &Dataset, start: usize, rows: usize, chunk: usize, values: &[f64], encoder: &mut ChunkEncoder) -> Result<(), Error> {
    let mut shape = ds.shape();
    let row: usize = shape[1..].iter().product();
    // Not asserts: a file changed underneath (another run writing the same case, a full
    // disk that failed a resize) must fail the case, not abort the process.
    if start % chunk != 0 || values.len() != rows * row || shape[0] != start {
        return Err(format!(
            "{}: block of {} values at row {start} does not continue the dataset ({shape:?}); was the file changed by another process?",
            ds.name(),
            values.len()
        )
        .into());
    }
    shape[0] = start + rows;
    ds.resize(shape.clone())?;
    if row == 0 {
        return Ok(());
    }
    let bytes = encoder.encode(values, chunk * row)?;
    let offset: Vec<hsize_t> = std::iter::once(start as hsize_t).chain(shape[1..].iter().map(|_| 0)).collect();
    let _lock = hdf5_sys::LOCK.lock();
    // SAFETY: `offset` has the dataset's rank and names a chunk inside its new extent;
    // `bytes` is that chunk after the dataset's filter pipeline.
    let err = unsafe {
        hdf5_sys::h5d::H5Dwrite_chunk(
            ds.id(),
            hdf5_sys::h5p::H5P_DEFAULT,
            0,
            offset.as_ptr(),
            bytes.len(),
            bytes.as_ptr().cast(),
        )
    };
    check(err, "H5Dwrite_chunk")
}

/// Writes all of `ds` from `values`, with a conversion buffer the size of `values`.
///
/// Why not `write_raw`: HDF5's default transfer buffer is 1 MiB, and a conversion with a
/// background buffer (variable-length strings have one) callocs that much at every write,
/// fresh pages each time. On the benchmark deployment (one case, outputs off) the labels
/// of `collected.h5` took 780 of the process's 1 846 page faults that way, several ms of
/// a 0.09 s run.
/// Bytes of a variable-length element in a file (a 4-byte length and an 8-byte address
/// and 4-byte index into the global heap).
const VLEN_ON_DISK: usize = 16;

fn write_whole<T: H5Type>(ds: &Dataset, values: &[T]) -> Result<(), Error> {
    if values.len() != ds.size() {
        return Err(format!("HDF5: {} values for {}, which holds {}", values.len(), ds.name(), ds.size()).into());
    }
    if values.is_empty() {
        return Ok(());
    }
    let mem = hdf5::Datatype::from_type::<T>()?;
    // Room for every element at the larger of the two types' sizes, and at least
    // VLEN_ON_DISK: HDF5 refuses a buffer that cannot hold one element, and a
    // variable-length string's size on disk is more than either datatype says (HDF5 then
    // converts in more than one pass).
    let bytes = (values.len() * mem.size().max(ds.dtype()?.size())).max(VLEN_ON_DISK);
    let _lock = hdf5_sys::LOCK.lock();
    // SAFETY: `ds` and `mem` are open; `values` holds the dataset's every element in
    // `mem`'s layout (H5Type); the property list is closed before returning.
    unsafe {
        let dxpl = H5Pcreate(*H5P_CLS_DATASET_XFER);
        if dxpl < 0 {
            return Err("HDF5: H5Pcreate (dataset transfer) failed".into());
        }
        let mut err = H5Pset_buffer(dxpl, bytes, std::ptr::null_mut(), std::ptr::null_mut());
        if err >= 0 {
            err = H5Dwrite(ds.id(), mem.id(), H5S_ALL, H5S_ALL, dxpl, values.as_ptr().cast());
        }
        H5Pclose(dxpl);
        check(err, "H5Dwrite")
    }
}

fn check(err: herr_t, what: &str) -> Result<(), Error> {
    if err < 0 {
        return Err(format!("HDF5: {what} failed").into());
    }
    Ok(())
}

fn describe(ds: &Dataset, units: &str, long_name: &str) -> Result<(), Error> {
    str_attr(ds, "units", units)?;
    str_attr(ds, "long_name", long_name)
}

pub(super) fn str_attr(loc: &Location, name: &str, value: &str) -> Result<(), Error> {
    loc.new_attr::<VarLenUnicode>()
        .create(name)?
        .write_scalar(&value.parse::<VarLenUnicode>()?)?;
    Ok(())
}

pub(super) fn varlen<S: AsRef<str>>(values: &[S]) -> Result<Vec<VarLenUnicode>, Error> {
    values.iter().map(|s| Ok(s.as_ref().parse()?)).collect()
}

/// Appends the vectors' components: three-value copies, where a flattening iterator, of
/// unknown length, cost the writer 3 % of its time on the paper case (perf).
fn extend_vectors(buf: &mut Vec<f64>, v: &[Vector3<f64>]) {
    buf.reserve(3 * v.len());
    for p in v {
        buf.extend_from_slice(p.as_slice());
    }
}

fn flat(v: &[Vector3<f64>]) -> Vec<f64> {
    v.iter().flat_map(|p| p.iter().copied()).collect()
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::model::generate::TowerSpec;
    use crate::model::Model;
    use crate::record::{Constraints, EigenRecord, Energy, Nearest};

    /// A path `name` in a fresh directory, which is removed when the guard is dropped.
    pub(in crate::output) fn temp_path(name: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::Builder::new().prefix("tsim-record-").tempdir().unwrap();
        let path = dir.path().join(name);
        (dir, path)
    }

    /// Drives `rec` through every stage of a synthetic case: form-finding, eigen, then steps
    /// 0..=steps of free vibration (dt 0.01 s), folding and deployment, of which, like the
    /// stages, it records those with `step % every == 0` and the last. Energies are (step,
    /// 2 step, 3 step, 4 step).
    pub(in crate::output) fn drive(rec: &mut dyn Recorder, model: &Model, steps: usize, every: usize) -> RecordResult {
        let (n, m) = (model.node_count(), model.members.len());
        let x0 = model.positions();
        // Folding prescribes z of the last node besides the supports.
        let folding = Constraints::new(model, &[(n - 1, 2)]);
        let layout = |kind, name| StageLayout::plain(model, Stage::new(kind, name));
        let stages = [
            StageLayout {
                placeholder: true,
                ..layout(StageKind::Static, "static")
            },
            layout(StageKind::Eigen, "eigen"),
            layout(StageKind::Transient, "free_vibration"),
            StageLayout {
                constraints: folding.clone(),
                ..layout(StageKind::Folding, "folding")
            },
            StageLayout {
                actuated: true,
                ..layout(StageKind::Transient, "deployment")
            },
        ];
        rec.model(&ModelRecord {
            model,
            rest_lengths: &vec![1.0; m],
            masses: &vec![2.0; n],
            mass_reading: "paper",
            stages: &stages,
        })?;
        let forces: Vec<f64> = model
            .members
            .iter()
            .map(|mb| if mb.kind == crate::model::MemberKind::Strut { -10.0 } else { 5.0 })
            .collect();
        rec.formfinding(&FormFindRecord {
            stage: &Stage::of(StageKind::FormFinding),
            residuals: &[1.0, 1e-3, 1e-9],
            positions: &x0,
            forces: &forces,
            clearance: None,
        })?;
        // The analysis itself is tested in crate::rigidity; here it is only written.
        let analysis = crate::rigidity::analyse(model, &x0, None).map_err(|e| e.to_string())?;
        rec.rigidity(&RigidityRecord { analysis: Ok(&analysis) })?;
        let shapes = vec![vec![Vector3::new(0.0, 0.0, 1.0); n]; 4];
        rec.eigen(&EigenRecord {
            stage: &stages[1].stage,
            omega2: &[1.0, 4.0, 9.0, 16.0],
            mode_shapes: &shapes,
            rayleigh_alpha: 0.1,
            rayleigh_beta: 0.01,
            damping_modes: &[1, 2],
            damping_ratio: &[0.02, 0.02],
        })?;
        for StageLayout {
            stage,
            constraints,
            actuated,
            ..
        } in &stages[2..]
        {
            let is_folding = stage.kind == StageKind::Folding;
            rec.begin_stage(stage, constraints)?;
            for step in (0..=steps).filter(|s| s % every == 0 || *s == steps) {
                let s = step as f64;
                let positions: Vec<_> = x0.iter().map(|p| p + Vector3::repeat(1e-3 * s)).collect();
                let velocities = vec![Vector3::repeat(s); n];
                let time = if is_folding { s / steps as f64 } else { 0.01 * s };
                let energy = Energy {
                    kinetic: s,
                    strain: 2.0 * s,
                    damping: 3.0 * s,
                    external: 4.0 * s,
                    actuation: 5.0 * s,
                };
                let rest = vec![1.0 - 0.001 * s; m];
                let lengths = vec![1.0 + s; m];
                let velocities = (!is_folding).then_some(velocities.as_slice());
                // Struts 0 and 1 approach by 0.01 m a step; a touch is reported at the last.
                let touch = ClearanceEvent {
                    kind: EventKind::Touch,
                    members: [0, 1],
                    step,
                    time,
                    clearance: -0.01 * s,
                };
                let events = if step == steps { vec![touch] } else { vec![] };
                let nearest = Nearest {
                    clearance: -0.01 * s,
                    members: [0, 1],
                    points: [Vector3::zeros(); 2],
                    radius: 0.05,
                };
                rec.frame(&Frame {
                    step,
                    time,
                    positions: &positions,
                    velocities,
                    forces: &forces,
                    lengths: &lengths,
                    rest_lengths: actuated.then_some(rest.as_slice()),
                    energy,
                    applied: &vec![Vector3::new(0.0, 0.0, -s); n],
                    reactions: &(0..constraints.len()).map(|k| k as f64 + s).collect::<Vec<_>>(),
                    equilibrium_error: 1e-12 * s,
                    modes: None,
                    clearance: Some(crate::record::FrameClearance {
                        nearest: Some(nearest),
                        events: &events,
                    }),
                })?;
            }
            rec.end_stage(stage)?;
        }
        Ok(())
    }

    pub(in crate::output) fn status(path: &Path) -> String {
        let file = File::open(path).unwrap();
        file.attr("status")
            .unwrap()
            .read_scalar::<FixedUnicode<STATUS_LEN>>()
            .unwrap()
            .as_str()
            .to_string()
    }

    #[test]
    fn writes_the_layout_and_status() {
        let model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let (_dir, path) = temp_path("layout.h5");
        let mut rec = Hdf5Recorder::create(&path, "case-7", "a: 1\n").unwrap();
        // Stride 3 over steps 0..=10: the last step is not a multiple of 3.
        drive(&mut rec, &model, 10, 3).unwrap();
        assert_eq!(status(&path), "running");
        rec.finish(&Outcome::Complete).unwrap();
        assert_eq!(status(&path), "complete");

        let file = File::open(&path).unwrap();
        assert_eq!(
            file.attr("case_id").unwrap().read_scalar::<VarLenUnicode>().unwrap().as_str(),
            "case-7"
        );
        assert_eq!(
            file.attr("units").unwrap().read_scalar::<VarLenUnicode>().unwrap().as_str(),
            "SI (m, N, kg, s)"
        );
        let (n, m) = (6, 12);
        assert_eq!(file.dataset("model/member_nodes").unwrap().shape(), vec![m, 2]);
        let mass = file.dataset("model/mass").unwrap();
        assert_eq!(
            mass.attr("mass_reading").unwrap().read_scalar::<VarLenUnicode>().unwrap().as_str(),
            "paper"
        );
        assert_eq!(file.dataset("eigen/mode_shape").unwrap().shape(), vec![4, n, 3]);
        assert_eq!(
            file.group("eigen")
                .unwrap()
                .attr("damping_modes")
                .unwrap()
                .read_raw::<i64>()
                .unwrap(),
            vec![1, 2]
        );
        // Steps 0, 3, 6, 9 and the last, 10.
        let time = file.dataset("free_vibration/time").unwrap().read_raw::<f64>().unwrap();
        assert_eq!(time, [0.0, 3.0, 6.0, 9.0, 10.0].map(|s| 0.01 * s));
        assert_eq!(
            file.dataset("folding/time").unwrap().read_raw::<f64>().unwrap(),
            vec![0.0, 3.0, 6.0, 9.0, 10.0]
        );
        assert_eq!(
            file.dataset("folding/fraction").unwrap().read_raw::<f64>().unwrap(),
            vec![0.0, 0.3, 0.6, 0.9, 1.0]
        );
        assert_eq!(file.dataset("deployment/position").unwrap().shape(), vec![5, n, 3]);
        assert_eq!(file.dataset("deployment/velocity").unwrap().shape(), vec![5, n, 3]);
        assert!(file.dataset("folding/velocity").is_err());
        assert_eq!(
            file.dataset("deployment/kinetic_energy").unwrap().read_raw::<f64>().unwrap(),
            vec![0.0, 3.0, 6.0, 9.0, 10.0]
        );
        assert_eq!(file.dataset("deployment/member_length").unwrap().shape(), vec![5, m]);
        // The actuated stage (deployment in `drive`) records rest lengths and the actuators'
        // work; the others do not have them.
        let rest = file.dataset("deployment/rest_length").unwrap().read_2d::<f64>().unwrap();
        assert_eq!(rest.shape(), [5, m]);
        assert_eq!(rest[[4, 0]], 1.0 - 0.001 * 10.0);
        assert_eq!(
            file.dataset("deployment/actuator_work").unwrap().read_raw::<f64>().unwrap(),
            vec![0.0, 15.0, 30.0, 45.0, 50.0]
        );
        assert!(file.dataset("free_vibration/rest_length").is_err() && file.dataset("free_vibration/actuator_work").is_err());
        // 6 supported directions, and in folding the prescribed z of the last node.
        assert_eq!(file.dataset("deployment/reaction").unwrap().shape(), vec![5, 6]);
        let reaction = file.dataset("folding/reaction").unwrap().read_raw::<f64>().unwrap();
        assert_eq!(reaction.len(), 5 * 7);
        assert_eq!(reaction[7..14], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0].map(|k| k + 3.0));
        let labels = |name: &str| -> Vec<String> {
            let ds = file.dataset(name).unwrap();
            ds.read_raw::<VarLenUnicode>().unwrap().iter().map(|s| s.to_string()).collect()
        };
        assert_eq!(labels("folding/support")[6], format!("{}.z", model.nodes[n - 1].id));
        assert_eq!(labels("folding/support_kind")[6], "prescribed");
        assert_eq!(labels("folding/support_node")[0], model.nodes[0].id);
        assert_eq!(labels("deployment/support_axis")[..2], ["x", "y"]);
        assert_eq!(
            file.dataset("free_vibration/applied_load").unwrap().read_raw::<f64>().unwrap()[3 * n * 4 + 2],
            -10.0
        );
        assert_eq!(
            file.dataset("folding/equilibrium_error").unwrap().read_raw::<f64>().unwrap()[4],
            1e-12 * 10.0
        );
        assert_eq!(
            file.dataset("structure_analysis/mechanism").unwrap().shape(),
            vec![
                3 * n - model.support_count(),
                file.group("structure_analysis")
                    .unwrap()
                    .attr("m_internal")
                    .unwrap()
                    .read_scalar::<i64>()
                    .unwrap() as usize
            ]
        );
        let read = |name: &str| file.dataset(name).unwrap().read_raw::<f64>().unwrap();
        assert_eq!(read("deployment/min_clearance"), [0.0, 3.0, 6.0, 9.0, 10.0].map(|s| -0.01 * s));
        assert_eq!(read("folding/min_clearance_pair"), [0.0, 1.0].repeat(5));
        assert_eq!(read("folding/clearance_event_time"), [1.0]);
        assert_eq!(read("deployment/clearance_event_clearance"), [-0.1]);
        let ints = |name: &str| file.dataset(name).unwrap().read_raw::<i64>().unwrap();
        assert_eq!(ints("deployment/clearance_event_step"), [10]);
        assert_eq!(ints("deployment/clearance_event_pair"), [0, 1]);
        assert_eq!(
            file.dataset("deployment/clearance_event_kind").unwrap().read_raw::<i8>().unwrap(),
            [0]
        );
        assert!(file.dataset("formfinding/min_clearance").is_err(), "not followed there");
        for group in [
            "model",
            "formfinding",
            "structure_analysis",
            "eigen",
            "free_vibration",
            "folding",
            "deployment",
        ] {
            let g = file.group(group).unwrap();
            for name in g.member_names().unwrap() {
                let ds = g.dataset(&name).unwrap();
                let attrs = ds.attr_names().unwrap();
                assert!(
                    attrs.contains(&"units".to_string()) && attrs.contains(&"long_name".to_string()),
                    "{group}/{name}"
                );
                // A dimension scale (CLASS) or attached to scales (DIMENSION_LIST).
                assert!(
                    attrs.contains(&"CLASS".to_string()) || attrs.contains(&"DIMENSION_LIST".to_string()),
                    "{group}/{name}: {attrs:?}"
                );
            }
        }
    }

    #[test]
    fn streams_in_chunks_and_reports_failure() {
        let model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let (_dir, path) = temp_path("chunks.h5");
        let mut rec = Hdf5Recorder::create(&path, "c", "").unwrap();
        drive(&mut rec, &model, 600, 1).unwrap();
        rec.finish(&Outcome::Failed("é".repeat(400))).unwrap();
        let file = File::open(&path).unwrap();
        let time = file.dataset("free_vibration/time").unwrap();
        assert_eq!(time.shape(), vec![601]);
        assert_eq!(time.chunk(), Some(vec![CHUNK_STEPS]));
        assert_eq!(
            file.dataset("free_vibration/strain_energy").unwrap().read_raw::<f64>().unwrap()[600],
            1200.0
        );
        let status = status(&path);
        assert!(status.starts_with("failed: é") && status.len() <= STATUS_LEN && status.len() >= STATUS_LEN - 1);
    }

    /// A model without supports has an empty `support` dimension (folding here still
    /// prescribes one direction): the datasets exist and are written.
    #[test]
    fn a_model_without_supports_has_an_empty_support_dimension() {
        let mut model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        model.nodes.iter_mut().for_each(|n| n.support = [false; 3]);
        let (_dir, path) = temp_path("free.h5");
        let mut rec = Hdf5Recorder::create(&path, "c", "").unwrap();
        drive(&mut rec, &model, 5, 1).unwrap();
        rec.finish(&Outcome::Complete).unwrap();
        let file = File::open(&path).unwrap();
        assert_eq!(file.dataset("deployment/reaction").unwrap().shape(), vec![6, 0]);
        assert_eq!(file.dataset("deployment/support").unwrap().shape(), vec![0]);
        assert_eq!(file.dataset("folding/reaction").unwrap().shape(), vec![6, 1]);
        assert_eq!(file.dataset("deployment/applied_load").unwrap().shape(), vec![6, 6, 3]);
    }

    #[test]
    fn dropped_recorder_is_not_complete() {
        let model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let (_dir, path) = temp_path("dropped.h5");
        let mut rec = Hdf5Recorder::create(&path, "c", "").unwrap();
        rec.model(&ModelRecord {
            model: &model,
            rest_lengths: &[1.0; 12],
            masses: &[1.0; 6],
            mass_reading: "physical",
            stages: &[StageLayout::plain(&model, Stage::new(StageKind::Transient, "free_vibration"))],
        })
        .unwrap();
        rec.begin_stage(&Stage::new(StageKind::Transient, "free_vibration"), &Constraints::new(&model, &[]))
            .unwrap();
        drop(rec);
        assert_eq!(status(&path), "failed: recorder dropped before finish");
    }
}
