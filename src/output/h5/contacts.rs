//! A stage's contact table in `result.h5`: one row per contact within the activation
//! distance at every recorded step, along the dimension `contact` (empty without
//! `contact`): the step and time, what touches, the gap, the force, the point and the
//! normal. A contact force is a sparse, changing set, so it is a table, not a (time, pair)
//! array; `contact_step` indexes it by step.

use super::netcdf::{append_rows, describe, extendable, Dims};
use super::Error;
use crate::contact::{Active, Touch};
use hdf5::Dataset;
use nalgebra::Vector3;

/// The contact table of one stage.
pub(super) struct ContactTable {
    index: Dataset,
    step: Dataset,
    time: Dataset,
    pair: Dataset,
    node: Dataset,
    gap: Dataset,
    force: Dataset,
    point: Dataset,
    normal: Dataset,
    rows: usize,
}

impl ContactTable {
    /// The table's datasets in `g` (whose `pair` and `xyz` dimensions exist); `folding`:
    /// its time is the applied fraction.
    pub(super) fn create(g: &mut Dims, folding: bool) -> Result<Self, Error> {
        let index = extendable::<i64>(&g.group, "contact", 1)?;
        describe(
            &index,
            "1",
            "contact row: a contact within the activation distance at a recorded step",
        )?;
        g.scale("contact", index.clone())?;
        let column = |name: &str, width: usize, dims: &[&str], units: &str, long_name: &str| -> Result<Dataset, Error> {
            let ds = if name.ends_with("step") || name.ends_with("pair") || name.ends_with("node") {
                extendable::<i64>(&g.group, name, width)?
            } else {
                extendable::<f64>(&g.group, name, width)?
            };
            describe(&ds, units, long_name)?;
            g.attach(&ds, dims)?;
            Ok(ds)
        };
        let row = ["contact"];
        let (time_units, time_name) = if folding {
            ("1", "applied fraction")
        } else {
            ("s", "time since the stage began")
        };
        Ok(ContactTable {
            step: column("contact_step", 1, &row, "1", "recorded step of the contact")?,
            time: column("contact_time", 1, &row, time_units, time_name)?,
            pair: column(
                "contact_pair",
                2,
                &["contact", "pair"],
                "1",
                "0-based member indices of the two struts, lower first (-1, -1: a node on the ground)",
            )?,
            node: column("contact_node", 1, &row, "1", "0-based node on the ground (-1: a strut pair)")?,
            gap: column("contact_gap", 1, &row, "m", "gap between the surfaces (> 0)")?,
            force: column("contact_force", 1, &row, "N", "force pressing the two apart (≥ 0)")?,
            point: column(
                "contact_point",
                3,
                &["contact", "xyz"],
                "m",
                "contact point: the midpoint of the struts' closest axis points, or the node's foot on the ground",
            )?,
            normal: column(
                "contact_normal",
                3,
                &["contact", "xyz"],
                "1",
                "unit normal: the force on the higher-numbered strut (or on the node) is contact_force times it",
            )?,
            index,
            rows: 0,
        })
    }

    /// Appends the contacts of recorded step `step` at `time`.
    pub(super) fn append(&mut self, step: usize, time: f64, contacts: &[Active]) -> Result<(), Error> {
        if contacts.is_empty() {
            return Ok(());
        }
        let (start, end) = (self.rows, self.rows + contacts.len());
        let column = |f: &dyn Fn(&Active) -> f64| contacts.iter().map(f).collect::<Vec<f64>>();
        append_rows(&self.index, start, &(start as i64..end as i64).collect::<Vec<_>>())?;
        append_rows(&self.step, start, &vec![step as i64; contacts.len()])?;
        append_rows(&self.time, start, &vec![time; contacts.len()])?;
        let node = |c: &Active| match c.touch {
            Touch::Ground(n) => n as i64,
            Touch::Struts(_) => -1,
        };
        append_rows(&self.node, start, &contacts.iter().map(node).collect::<Vec<_>>())?;
        append_rows(&self.gap, start, &column(&|c| c.gap))?;
        append_rows(&self.force, start, &column(&|c| c.force))?;
        self.pair.resize(vec![end, 2])?;
        for side in 0..2 {
            let member = |c: &Active| match c.touch {
                Touch::Struts(m) => m[side] as i64,
                Touch::Ground(_) => -1,
            };
            self.pair
                .write_slice(&contacts.iter().map(member).collect::<Vec<_>>(), (start..end, side))?;
        }
        let vectors = |ds: &Dataset, of: fn(&Active) -> Vector3<f64>| -> Result<(), Error> {
            ds.resize(vec![end, 3])?;
            for axis in 0..3 {
                ds.write_slice(&column(&|c| of(c)[axis]), (start..end, axis))?;
            }
            Ok(())
        };
        vectors(&self.point, |c| c.point)?;
        vectors(&self.normal, |c| c.normal)?;
        self.rows = end;
        Ok(())
    }
}
