//! The streamed groups of `result.h5`: one time-stepping stage's datasets, its buffered
//! block of steps, its clearance event table and its contact table.

use super::contacts::ContactTable;
use super::netcdf::{append_chunk, append_rows, extend_vectors, extendable};
use super::netcdf::{describe, str_attr, varlen, Dims};
use super::{Error, GZIP_LEVEL, MIN_CLEARANCE, MIN_CLEARANCE_PAIR, PAIR};
use crate::model::{Cluster, AXES};
use crate::output::chunk::ChunkEncoder;
use crate::record::{ClearanceEvent, Constraints, EventKind, Frame, ModelRecord, StageLayout};

use hdf5::{Dataset, Group};

/// Node and member ids, the labels of the `node` and `member` dimensions.
#[derive(Clone, Copy)]
pub(super) struct Ids<'a> {
    pub(super) nodes: &'a [String],
    pub(super) members: &'a [String],
}

/// The datasets of one time-stepping stage and the block of steps not yet written.
pub(super) struct Series {
    /// (dataset, buffered values of its rows not yet written)
    columns: Vec<(Dataset, Vec<f64>)>,
    /// The directions of the `support` dimension (the reactions' order).
    pub(super) constraints: Constraints,
    folding: bool,
    /// Lowest modes recorded per step (folding with `folding.eigen`; 0: none).
    modes: usize,
    /// Whether the stage changes rest lengths in time (`rest_length`, `actuator_work`).
    actuated: bool,
    /// The clustered cables with the rest lengths their slides count from
    /// (`cluster_tension`, `pulley_slide`; empty: none).
    clusters: Vec<Cluster>,
    reference_rest: Vec<f64>,
    events: EventTable,
    contacts: ContactTable,
    written: usize,
    buffered: usize,
    chunk: usize,
    encoder: ChunkEncoder,
}

/// The streamed member forces (in a `dynamic` stage with their viscous part) and lengths,
/// the energies and, in an `actuated` stage, the rest lengths and the actuators' work, in
/// [`Series::push`]'s order.
fn member_and_energy_columns(g: &Dims, dynamic: bool, actuated: bool, chunk: usize) -> Result<Vec<Dataset>, Error> {
    let mut columns = vec![g.streamed(
        "member_force",
        &["member"],
        chunk,
        "N",
        if dynamic {
            "member axial force, elastic + viscous (tension > 0)"
        } else {
            "member axial force (tension > 0)"
        },
    )?];
    if dynamic {
        columns.push(g.streamed(
            "member_force_viscous",
            &["member"],
            chunk,
            "N",
            "viscous part of member_force: the member's damping force along it (the elastic part is member_force - member_force_viscous)",
        )?);
    }
    for (name, units, long_name) in [
        ("member_length", "m", "member length"),
        ("kinetic_energy", "J", "kinetic energy"),
        ("strain_energy", "J", "strain energy"),
        (
            "contact_energy",
            "J",
            "barrier energy of the contacts (0 without `contact`; in static stages its change since the stage began, as strain_energy)",
        ),
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

/// A clustered structure's `cluster` and `pulley` dimensions (labels: the cluster ids, and
/// `<cluster>.<node>` for each pulley between two listed members) and their streamed
/// `cluster_tension` and `pulley_slide` ([`Cluster::slides`]).
fn cluster_columns(g: &mut Dims, record: &ModelRecord, chunk: usize) -> Result<Vec<Dataset>, Error> {
    let (model, clusters) = (record.model, &record.model.clusters);
    g.labels(
        "cluster",
        &clusters.iter().map(|c| c.id.as_str()).collect::<Vec<_>>(),
        "clustered cable id",
    )?;
    let pulleys: Vec<String> = clusters
        .iter()
        .flat_map(|c| c.pulleys().iter().map(move |&n| format!("{}.{}", c.id, model.nodes[n].id)))
        .collect();
    g.labels(
        "pulley",
        &pulleys,
        "a clustered cable's pulley node between two of its listed members (cluster.node)",
    )?;
    Ok(vec![
        g.streamed(
            "cluster_tension",
            &["cluster"],
            chunk,
            "N",
            "the cable's one tension, elastic + viscous (that of each of its members)",
        )?,
        g.streamed(
            "pulley_slide",
            &["pulley"],
            chunk,
            "m",
            "cable (as rest length) run over the pulley towards the cable's first member since substitution, less a winch's uniform change",
        )?,
    ])
}

/// The `node`, `member`, `xyz` and `support` dimensions with their labels, and the
/// support's auxiliary coordinates (node, axis, kind of each constrained direction).
fn dimensions(g: &mut Dims, constraints: &Constraints, ids: Ids, record: &ModelRecord) -> Result<(), Error> {
    g.labels("node", ids.nodes, "node id")?;
    g.labels("member", ids.members, "member id")?;
    g.labels("xyz", &AXES, "coordinate axis")?;
    g.labels(
        "support",
        &constraints.labels(record.model),
        "constrained direction (node.axis): a support, or prescribed by the stage",
    )?;
    let support_node: Vec<&str> = constraints.0.iter().map(|c| ids.nodes[c.node].as_str()).collect();
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
    )
}

/// The streamed applied loads, reactions and equilibrium error, in that order.
fn load_columns(g: &Dims, chunk: usize) -> Result<Vec<Dataset>, Error> {
    let mut columns = Vec::new();
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
    Ok(columns)
}

/// The `mode` dimension and the streamed lowest `modes` eigenvalues and lowest mode of a
/// folding path.
fn mode_columns(g: &mut Dims, modes: usize, chunk: usize) -> Result<[Dataset; 2], Error> {
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
    Ok([omega2, lowest])
}

impl Series {
    /// Column order, used by [`Series::push`]: time, [fraction], position, [velocity],
    /// member_force, [member_force_viscous (transient stages)], member_length, kinetic, strain, damping, external, [rest_length,
    /// actuator_work (a stage in `record.actuated`)], applied_load,
    /// reaction, equilibrium_error, [mode_omega2, lowest_mode], min_clearance,
    /// min_clearance_pair; the clearance events in a table of their own. Folding, a static stage, has `fraction` and no
    /// `velocity`. The `support` dimension (the stage's constrained directions, from
    /// `record`) has the coordinate `support` (labels `<node>.<axis>`) and the auxiliary
    /// coordinates `support_node`, `support_axis` and `support_kind` (`support` or
    /// `prescribed`).
    pub(super) fn create(group: Group, layout: &StageLayout, ids: Ids, record: &ModelRecord, chunk: usize) -> Result<Self, Error> {
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
        dimensions(&mut g, &constraints, ids, record)?;
        let mut columns = vec![time];
        if folding {
            let what = layout.stage.kind.fraction().unwrap_or_default();
            columns.push(g.streamed("fraction", &[], chunk, "1", what)?);
        }
        columns.push(g.streamed("position", &["node", "xyz"], chunk, "m", "node position")?);
        if !folding {
            columns.push(g.streamed("velocity", &["node", "xyz"], chunk, "m s-1", "node velocity")?);
        }
        let actuated = layout.actuated;
        columns.extend(member_and_energy_columns(&g, !folding, actuated, chunk)?);
        // With the rest lengths they are found from: a clustered structure's stages record them.
        let clusters = if actuated { record.model.clusters.clone() } else { Vec::new() };
        if !clusters.is_empty() {
            columns.extend(cluster_columns(&mut g, record, chunk)?);
        }
        columns.extend(load_columns(&g, chunk)?);
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
            columns.extend(mode_columns(&mut g, modes, chunk)?);
        }
        let (clearance, events) = clearance_columns(&mut g, folding, chunk)?;
        columns.extend(clearance);
        let contacts = ContactTable::create(&mut g, folding)?;
        let columns = columns.into_iter().map(|ds| (ds, Vec::new())).collect();
        Ok(Series {
            columns,
            constraints,
            folding,
            modes,
            actuated,
            clusters,
            reference_rest: record.rest_lengths.to_vec(),
            events,
            contacts,
            written: 0,
            buffered: 0,
            chunk,
            encoder: ChunkEncoder::new(GZIP_LEVEL.into()),
        })
    }

    /// Buffers a frame; writes the block when it fills a chunk, and then says so (true): a
    /// SWMR reader sees the new steps only once the caller flushes the file.
    pub(super) fn push(&mut self, f: &Frame) -> Result<bool, Error> {
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
        if !self.folding {
            let viscous = f
                .viscous_forces
                .ok_or_else(|| format!("HDF5: frame {} of a transient stage lacks its viscous member forces", f.step))?;
            next().extend_from_slice(viscous);
        }
        next().extend_from_slice(f.lengths);
        let e = f.energy;
        for value in [e.kinetic, e.strain, e.contact, e.damping, e.external] {
            next().push(value);
        }
        if self.actuated {
            let rest = f
                .rest_lengths
                .ok_or_else(|| format!("HDF5: frame {} of an actuated stage lacks its rest lengths", f.step))?;
            next().extend_from_slice(rest);
            next().push(e.actuation);
            if !self.clusters.is_empty() {
                next().extend(self.clusters.iter().map(|c| c.tension(f.forces)));
                let slides = next();
                self.clusters.iter().for_each(|c| c.slides(rest, &self.reference_rest, slides));
            }
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
        self.contacts.append(f.step, f.time, f.contacts)?;
        self.buffered += 1;
        let full = self.buffered == self.chunk;
        if full {
            self.write_block()?;
        }
        Ok(full)
    }

    /// Appends the buffered steps to every dataset; the caller flushes the file.
    pub(super) fn write_block(&mut self) -> Result<(), Error> {
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
    pub(super) fn create(g: &mut Dims, folding: bool) -> Result<Self, Error> {
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
