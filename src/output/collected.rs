//! `collected.h5`: a sweep's cases in one netCDF-4 file along a `case` dimension, written
//! by `tsim collect` (and at the end of `tsim run`). Laid out like `result.h5` (dimension
//! scales with their coordinate variables, `units` and `long_name` on every variable), so
//! `xarray.open_dataset(path, engine="h5netcdf")` gives one Dataset: the swept parameters
//! are coordinates along `case` (every variable's `coordinates` attribute names them), the
//! per-case scalars of `summary.csv`, the energy histories of each stage and its node
//! positions and member forces at up to [`MAX_FRAMES`] of its steps are variables.

use super::h5::{str_attr, untimed_file, varlen, Dims};
use hdf5::types::{FixedUnicode, VarLenUnicode};
use hdf5::File;
use std::path::Path;

type Error = Box<dyn std::error::Error + Send + Sync>;

/// Values along `case`.
#[derive(Clone, Debug, PartialEq)]
pub enum Column {
    /// NaN where a case has none.
    Numbers(Vec<f64>),
    /// Whole numbers (a swept axis whose labels all are: `steps: 4, 8, 16`).
    Integers(Vec<i64>),
    Texts(Vec<String>),
}

/// A variable (or coordinate) along `case`.
#[derive(Clone, Debug)]
pub struct Variable {
    pub name: String,
    pub units: String,
    pub long_name: String,
    pub values: Column,
}

/// One stage's energy histories, per case (empty for a case without them).
#[derive(Clone, Debug, Default)]
pub struct History {
    pub stage: String,
    /// The units of the stage's `time` (s; `1` for the static and folding steps).
    pub time_units: String,
    pub time: Vec<Vec<f64>>,
    pub kinetic: Vec<Vec<f64>>,
    pub strain: Vec<Vec<f64>>,
}

/// Most steps of a stage whose positions and forces are collected: every k-th recorded step,
/// k the least that keeps the longest case within this many (the main sweep's 27 cases:
/// 27 × 500 × (20 × 3 + 50) values, 12 MB per stage), so that a sweep's plot of a node or
/// member over time is one xarray selection and the file stays a fraction of the run's.
pub const MAX_FRAMES: usize = 500;

/// One stage's node positions and member forces at every `stride`-th recorded step, per
/// case (empty for a case without them), over the run's shared nodes and members.
#[derive(Clone, Debug, Default)]
pub struct Frames {
    pub stage: String,
    pub time_units: String,
    pub stride: usize,
    pub time: Vec<Vec<f64>>,
    /// frames × nodes × 3, flat.
    pub position: Vec<Vec<f64>>,
    /// frames × members, flat.
    pub force: Vec<Vec<f64>>,
}

/// Everything `collected.h5` holds.
#[derive(Clone, Debug, Default)]
pub struct Collection {
    /// Case ids, the `case` coordinate.
    pub ids: Vec<String>,
    /// The swept axes' coordinates along `case`.
    pub coords: Vec<Variable>,
    /// The per-case scalars.
    pub vars: Vec<Variable>,
    pub histories: Vec<History>,
    /// The node and member ids every case shares (empty: the cases' models differ, and
    /// no frames are collected), and the stages' frames.
    pub nodes: Vec<String>,
    pub members: Vec<String>,
    pub frames: Vec<Frames>,
    /// Root attributes (text).
    pub attrs: Vec<(String, String)>,
}

/// A stage's `time`, `kinetic_energy`, `strain_energy` and the units of its time.
pub type StageHistory = (Vec<f64>, Vec<f64>, Vec<f64>, String);

/// A stage's history from a finished `result.h5` (empty when the file has no such group).
pub fn read_history(path: &Path, stage: &str) -> Result<StageHistory, Error> {
    let file = File::open(path)?;
    let status: FixedUnicode<512> = file.attr("status")?.read_scalar()?;
    if status.as_str() != "complete" {
        return Err(format!("result.h5 status is `{}`", status.as_str()).into());
    }
    let Ok(group) = file.group(stage) else {
        return Ok(Default::default());
    };
    let time = group.dataset("time")?;
    let units: VarLenUnicode = time.attr("units")?.read_scalar()?;
    let read = |name: &str| -> Result<Vec<f64>, Error> { Ok(group.dataset(name)?.read_raw::<f64>()?) };
    Ok((
        time.read_raw()?,
        read("kinetic_energy")?,
        read("strain_energy")?,
        units.as_str().into(),
    ))
}

/// A case's node ids, member ids and each stage's recorded step count.
pub type Layout = (Vec<String>, Vec<String>, Vec<usize>);

/// A stage's `time`, `position` and `member_force` at some of its steps, and the units of
/// its time.
pub type StageFrames = (Vec<f64>, Vec<f64>, Vec<f64>, String);

/// The node and member ids of a finished `result.h5`, and each of `stages`' recorded step
/// count (0 where it has none).
pub fn read_layout(path: &Path, stages: &[String]) -> Result<Layout, Error> {
    let file = File::open(path)?;
    let model = file.group("model")?;
    let ids = |name: &str| -> Result<Vec<String>, Error> {
        Ok(model
            .dataset(name)?
            .read_raw::<VarLenUnicode>()?
            .iter()
            .map(|s| s.as_str().to_string())
            .collect())
    };
    let steps = stages
        .iter()
        .map(|s| file.group(s).and_then(|g| g.dataset("time")).map_or(0, |t| t.size()))
        .collect();
    Ok((ids("node")?, ids("member")?, steps))
}

/// A stage's time (and its units), node positions and member forces at every `stride`-th
/// recorded step of a finished `result.h5` (empty when the file has no such group).
pub fn read_frames(path: &Path, stage: &str, stride: usize) -> Result<StageFrames, Error> {
    use ndarray::s;
    let file = File::open(path)?;
    let Ok(group) = file.group(stage) else {
        return Ok(Default::default());
    };
    let time = group.dataset("time")?;
    let units: VarLenUnicode = time.attr("units")?.read_scalar()?;
    let position = group
        .dataset("position")?
        .read_slice::<f64, _, ndarray::Ix3>(s![..;stride, .., ..])?;
    let force = group
        .dataset("member_force")?
        .read_slice::<f64, _, ndarray::Ix2>(s![..;stride, ..])?;
    Ok((
        time.read_slice_1d::<f64, _>(s![..;stride])?.to_vec(),
        position.iter().copied().collect(),
        force.iter().copied().collect(),
        units.as_str().into(),
    ))
}

/// Whether every case's times are the first entries of the longest case's: then the
/// stage gets one time coordinate, else a step index with a time per case.
fn shared_time(times: &[Vec<f64>]) -> Option<&Vec<f64>> {
    let longest = times.iter().max_by_key(|t| t.len())?;
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-300);
    times
        .iter()
        .all(|t| t.iter().zip(longest).all(|(&a, &b)| same(a, b)))
        .then_some(longest)
}

/// Each case's `rows` padded with NaN to `len` values, one after another.
fn pad(rows: &[Vec<f64>], len: usize) -> Vec<f64> {
    rows.iter()
        .flat_map(|r| r.iter().copied().chain(std::iter::repeat(f64::NAN)).take(len))
        .collect()
}

/// The dimension a stage's per-case series run along: the time coordinate `names.0` where
/// every case's `times` are the first of the longest case's, else a step index `names.1`
/// with the times a (case, step) variable named `names.0`. Returns the dimension and the
/// coordinates its variables name (the swept axes', and those times where they vary).
fn time_dimension(
    dims: &mut Dims,
    (time_name, step): &(String, String),
    times: &[Vec<f64>],
    (units, long): (&str, &str),
    coordinates: &str,
) -> Result<(String, String), Error> {
    if let Some(t) = shared_time(times) {
        dims.coord(time_name, t, units, long)?;
        return Ok((time_name.clone(), coordinates.to_string()));
    }
    let len = times.iter().map(Vec::len).max().unwrap_or(0);
    let index: Vec<i64> = (0..len as i64).collect();
    dims.coord(step, &index, "1", &format!("{step}: recorded step index"))?;
    dims.var(time_name, &["case", step], &pad(times, len), units, long)?;
    name_coordinates(dims, time_name, coordinates)?;
    Ok((step.clone(), format!("{coordinates} {time_name}").trim().to_string()))
}

/// The `coordinates` attribute of variable `name`, unless there are none.
fn name_coordinates(dims: &Dims, name: &str, coordinates: &str) -> Result<(), Error> {
    if !coordinates.is_empty() {
        str_attr(&*dims.group.dataset(name)?, "coordinates", coordinates)?;
    }
    Ok(())
}

/// Writes `c` to `path` (replacing it).
pub fn write(path: &Path, c: &Collection) -> Result<(), Error> {
    let file = untimed_file().create(path)?;
    for (name, value) in &c.attrs {
        str_attr(&file, name, value)?;
    }
    let mut dims = Dims::new((*file).clone());
    dims.labels("case", &c.ids, "case id (its directory in the run)")?;
    let n = c.ids.len();
    let coordinates = c.coords.iter().map(|v| v.name.as_str()).collect::<Vec<_>>().join(" ");
    let column = |dims: &Dims, v: &Variable, coordinates: &str| -> Result<(), Error> {
        match &v.values {
            Column::Numbers(x) => dims.var(&v.name, &["case"], x, &v.units, &v.long_name)?,
            Column::Integers(x) => dims.var(&v.name, &["case"], x, &v.units, &v.long_name)?,
            Column::Texts(t) => dims.var(&v.name, &["case"], &varlen(t)?, &v.units, &v.long_name)?,
        }
        if !coordinates.is_empty() {
            str_attr(&*dims.group.dataset(&v.name)?, "coordinates", coordinates)?;
        }
        Ok(())
    };
    for v in &c.coords {
        column(&dims, v, "")?;
    }
    for v in &c.vars {
        column(&dims, v, &coordinates)?;
    }
    for h in &c.histories {
        let len = h.time.iter().map(Vec::len).max().unwrap_or(0);
        if len == 0 {
            continue;
        }
        let stage = &h.stage;
        let long = format!("{stage}: time since the stage began (static stages: the step)");
        let names = (format!("{stage}_time"), format!("{stage}_step"));
        let (dim, coords) = time_dimension(&mut dims, &names, &h.time, (&h.time_units, &long), &coordinates)?;
        for (name, rows, what) in [
            ("kinetic_energy", &h.kinetic, "kinetic energy"),
            ("strain_energy", &h.strain, "strain energy"),
        ] {
            let name = format!("{stage}_{name}");
            let what = format!("{stage}: {what} (NaN past a case's end)");
            dims.var(&name, &["case", &dim], &pad(rows, len), "J", &what)?;
            name_coordinates(&dims, &name, &coords)?;
        }
    }
    write_frames(&mut dims, c, &coordinates)?;
    debug_assert!(c.vars.iter().all(|v| match &v.values {
        Column::Numbers(x) => x.len() == n,
        Column::Integers(x) => x.len() == n,
        Column::Texts(t) => t.len() == n,
    }));
    Ok(())
}

/// The stages' positions and forces of `c` ([`Frames`]), with the `node`, `xyz` and
/// `member` dimensions they need; `coordinates`: the swept axes'.
fn write_frames(dims: &mut Dims, c: &Collection, coordinates: &str) -> Result<(), Error> {
    if c.frames.iter().any(|f| f.time.iter().any(|t| !t.is_empty())) {
        dims.labels("node", &c.nodes, "node id")?;
        dims.labels("xyz", &["x", "y", "z"], "axis")?;
        dims.labels("member", &c.members, "member id")?;
    }
    for f in &c.frames {
        let len = f.time.iter().map(Vec::len).max().unwrap_or(0);
        if len == 0 {
            continue;
        }
        let stage = &f.stage;
        let steps = format!("the recorded steps 0, {}, {}, ...", f.stride, 2 * f.stride);
        let long = format!("{stage}: time since the stage began (static stages: the step) at {steps}");
        let names = (format!("{stage}_frame_time"), format!("{stage}_frame"));
        let (dim, coords) = time_dimension(dims, &names, &f.time, (&f.time_units, &long), coordinates)?;
        let (nodes, members) = (c.nodes.len(), c.members.len());
        for (name, rows, width, var_dims, units, what) in [
            ("position", &f.position, 3 * nodes, &["node", "xyz"][..], "m", "node position"),
            (
                "member_force",
                &f.force,
                members,
                &["member"][..],
                "N",
                "member axial force (tension > 0)",
            ),
        ] {
            let name = format!("{stage}_{name}");
            let what = format!("{stage}: {what} at {steps} (NaN past a case's end)");
            let all_dims: Vec<&str> = ["case", dim.as_str()].into_iter().chain(var_dims.iter().copied()).collect();
            dims.var(&name, &all_dims, &pad(rows, len * width), units, &what)?;
            name_coordinates(dims, &name, &coords)?;
        }
    }
    Ok(())
}
