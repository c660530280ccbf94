//! `collected.h5`: a sweep's cases in one netCDF-4 file along a `case` dimension, written
//! by `tsim collect` (and at the end of `tsim run`). Laid out like `result.h5` (dimension
//! scales with their coordinate variables, `units` and `long_name` on every variable), so
//! `xarray.open_dataset(path, engine="h5netcdf")` gives one Dataset: the swept parameters
//! are coordinates along `case` (every variable's `coordinates` attribute names them), the
//! per-case scalars of `summary.csv` and the energy histories of each stage are variables.

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
        let pad = |rows: &[Vec<f64>]| -> Vec<f64> {
            rows.iter()
                .flat_map(|r| r.iter().copied().chain(std::iter::repeat(f64::NAN)).take(len))
                .collect()
        };
        let time_name = format!("{stage}_time");
        let long = format!("{stage}: time since the stage began (static stages: the step)");
        let (dim, coords) = match shared_time(&h.time) {
            Some(t) => {
                dims.coord(&time_name, t, &h.time_units, &long)?;
                (time_name.clone(), coordinates.clone())
            }
            None => {
                let step = format!("{stage}_step");
                let index: Vec<i64> = (0..len as i64).collect();
                dims.coord(&step, &index, "1", &format!("{stage}: recorded step index"))?;
                dims.var(&time_name, &["case", &step], &pad(&h.time), &h.time_units, &long)?;
                str_attr(&*dims.group.dataset(&time_name)?, "coordinates", &coordinates)?;
                (step, format!("{coordinates} {time_name}").trim().to_string())
            }
        };
        for (name, rows, what) in [
            ("kinetic_energy", &h.kinetic, "kinetic energy"),
            ("strain_energy", &h.strain, "strain energy"),
        ] {
            let name = format!("{stage}_{name}");
            dims.var(
                &name,
                &["case", &dim],
                &pad(rows),
                "J",
                &format!("{stage}: {what} (NaN past a case's end)"),
            )?;
            if !coords.is_empty() {
                str_attr(&*dims.group.dataset(&name)?, "coordinates", &coords)?;
            }
        }
    }
    debug_assert!(c.vars.iter().all(|v| match &v.values {
        Column::Numbers(x) => x.len() == n,
        Column::Integers(x) => x.len() == n,
        Column::Texts(t) => t.len() == n,
    }));
    Ok(())
}
