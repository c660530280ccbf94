//! `paraview/<stage>.vtkhdf`: every time-stepping stage as a transient VTKHDF
//! `UnstructuredGrid` (format 2.2), which ParaView (5.12 and later) and the `vtk` Python
//! package open directly, time steps and all.
//!
//! Why VTKHDF and not XDMF over result.h5: a VTKHDF file is one self-describing HDF5
//! file that VTK's own reader takes as it is, where an XDMF index must track result.h5's
//! layout and is read by the Xdmf readers, which the `vtk` wheels do not carry; the price
//! is a second copy of the positions and forces (outputs.paraview is off by default).
//!
//! Layout: the members are VTK_LINE cells between their nodes, written once and reused
//! by every step (`Steps/CellOffsets`, `ConnectivityIdOffsets` and `PartOffsets` zero);
//! the points move, one block of node positions per step (`Steps/PointOffsets`). Cell
//! data per step: `force` (axial, elastic + viscous, tension > 0 [N]), `viscous_force`
//! (transient stages); once for all steps: `strut` (1 strut, 0 cable). Point data per
//! step: `displacement` from the stage's first recorded step [m] and `velocity` [m/s]
//! (transient stages). Steps are buffered and appended in blocks; `Steps/NSteps` counts
//! only steps whose data is written, so a file of a killed run opens with the steps it has.

use super::h5::netcdf::append_rows;
use super::{replacing, Error};
use crate::model::MemberKind;
use crate::record::{Constraints, Frame, ModelRecord, RecordResult, Recorder, Stage};
use hdf5::types::FixedAscii;
use hdf5::{Dataset, File, Group};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// The case directory's subdirectory of the ParaView files.
pub const DIR: &str = "paraview";

/// Steps buffered before they are appended: a few HDF5 writes per block, not per step.
const BLOCK: usize = 256;

/// VTK's cell type of a line between two points.
const VTK_LINE: u8 = 3;

/// Writes each stage's `<dir>/<stage>.vtkhdf`.
pub struct ParaviewRecorder {
    dir: PathBuf,
    /// Each member's end nodes and whether it is a strut, from `model`.
    members: Vec<[usize; 2]>,
    struts: Vec<i8>,
    nodes: usize,
    stage: Option<StageFile>,
}

/// One stage's open file and the steps not yet appended.
struct StageFile {
    path: PathBuf,
    /// Keeps the file open (its datasets refer into it).
    _file: File,
    steps: Group,
    /// Per-step datasets, in [`Block`]'s order.
    times: Dataset,
    offsets: [Dataset; 6],
    points: Dataset,
    displacement: Dataset,
    velocity: Option<Dataset>,
    force: Dataset,
    viscous: Option<Dataset>,
    /// The stage's first positions, what `displacement` is measured from.
    start: Vec<Vector3<f64>>,
    written: usize,
    block: Block,
}

/// Buffered steps: times, and per step the nodes' positions, displacements and
/// velocities (3 values each) and the members' forces.
#[derive(Default)]
struct Block {
    times: Vec<f64>,
    points: Vec<f64>,
    displacement: Vec<f64>,
    velocity: Vec<f64>,
    force: Vec<f64>,
    viscous: Vec<f64>,
}

impl ParaviewRecorder {
    /// Writes into `dir` (created when the first stage begins).
    pub fn new(dir: &Path) -> Self {
        ParaviewRecorder {
            dir: dir.to_path_buf(),
            members: Vec::new(),
            struts: Vec::new(),
            nodes: 0,
            stage: None,
        }
    }

    /// Creates `<dir>/<stage>.vtkhdf` with the grid's topology and empty per-step datasets.
    fn open(&self, stage: &Stage) -> Result<StageFile, Error> {
        std::fs::create_dir_all(&self.dir)?;
        let path = self.dir.join(format!("{}.vtkhdf", stage.name()));
        let file = replacing(&path, |p| Ok(File::create(p)?))?;
        let root = file.create_group("VTKHDF")?;
        root.new_attr::<i64>().shape(2).create("Version")?.write(&[2_i64, 2])?;
        // A fixed-length ASCII string, as VTK's reader takes it.
        let kind = FixedAscii::<16>::from_ascii("UnstructuredGrid")?;
        root.new_attr::<FixedAscii<16>>().create("Type")?.write_scalar(&kind)?;
        let m = self.members.len();
        let whole = |name: &str, values: &[i64]| -> Result<(), Error> {
            root.new_dataset_builder().with_data(values).create(name)?;
            Ok(())
        };
        whole("NumberOfPoints", &[self.nodes as i64])?;
        whole("NumberOfCells", &[m as i64])?;
        whole("NumberOfConnectivityIds", &[2 * m as i64])?;
        let connectivity: Vec<i64> = self.members.iter().flat_map(|e| e.map(|n| n as i64)).collect();
        whole("Connectivity", &connectivity)?;
        whole("Offsets", &(0..=m).map(|e| 2 * e as i64).collect::<Vec<_>>())?;
        root.new_dataset_builder().with_data(&vec![VTK_LINE; m]).create("Types")?;
        let (cells, points) = (root.create_group("CellData")?, root.create_group("PointData")?);
        cells.new_dataset_builder().with_data(&self.struts).create("strut")?;
        let dynamic = !stage.is_static();
        let steps = root.create_group("Steps")?;
        steps.new_attr::<i64>().create("NSteps")?.write_scalar(&0_i64)?;
        let (cell_offsets, point_offsets) = (steps.create_group("CellDataOffsets")?, steps.create_group("PointDataOffsets")?);
        let offsets = [
            growing::<i64>(&steps, "PartOffsets", 1, BLOCK)?,
            growing::<i64>(&steps, "NumberOfParts", 1, BLOCK)?,
            growing::<i64>(&steps, "PointOffsets", 1, BLOCK)?,
            growing::<i64>(&steps, "CellOffsets", 1, BLOCK)?,
            growing::<i64>(&steps, "ConnectivityIdOffsets", 1, BLOCK)?,
            growing::<i64>(&cell_offsets, "strut", 1, BLOCK)?,
        ];
        // One step's rows per chunk, at least a block's worth of steps for small models.
        let (node_rows, member_rows) = (self.nodes.max(BLOCK), m.max(BLOCK));
        let per_step = |group: &Group, offsets: &Group, name: &str, (width, rows): (usize, usize)| -> Result<Dataset, Error> {
            growing::<i64>(offsets, name, 1, BLOCK)?;
            growing::<f64>(group, name, width, rows)
        };
        Ok(StageFile {
            path,
            times: growing::<f64>(&steps, "Values", 1, BLOCK)?,
            offsets,
            points: growing::<f64>(&root, "Points", 3, node_rows)?,
            displacement: per_step(&points, &point_offsets, "displacement", (3, node_rows))?,
            velocity: dynamic
                .then(|| per_step(&points, &point_offsets, "velocity", (3, node_rows)))
                .transpose()?,
            force: per_step(&cells, &cell_offsets, "force", (1, member_rows))?,
            viscous: dynamic
                .then(|| per_step(&cells, &cell_offsets, "viscous_force", (1, member_rows)))
                .transpose()?,
            steps,
            _file: file,
            start: Vec::new(),
            written: 0,
            block: Block::default(),
        })
    }
}

impl StageFile {
    /// Buffers `f`, appending the block when it is full.
    fn push(&mut self, f: &Frame, nodes: usize) -> Result<(), Error> {
        if self.start.is_empty() {
            self.start = f.positions.to_vec();
        }
        let b = &mut self.block;
        b.times.push(f.time);
        for (x, x0) in f.positions.iter().zip(&self.start).take(nodes) {
            b.points.extend_from_slice(x.as_slice());
            b.displacement.extend_from_slice((x - x0).as_slice());
        }
        if let Some(v) = f.velocities {
            v.iter().for_each(|v| b.velocity.extend_from_slice(v.as_slice()));
        }
        b.force.extend_from_slice(f.forces);
        if let Some(viscous) = f.viscous_forces {
            b.viscous.extend_from_slice(viscous);
        }
        if b.times.len() == BLOCK {
            self.flush(nodes)?;
        }
        Ok(())
    }

    /// Appends the buffered steps, their offsets last and `NSteps` after them, so that
    /// what `NSteps` counts is always whole.
    fn flush(&mut self, nodes: usize) -> Result<(), Error> {
        let (b, start) = (std::mem::take(&mut self.block), self.written);
        let count = b.times.len();
        if count == 0 {
            return Ok(());
        }
        let members = b.force.len() / count;
        append_rows(&self.times, start, &b.times)?;
        append_vectors(&self.points, start * nodes, &b.points)?;
        append_vectors(&self.displacement, start * nodes, &b.displacement)?;
        if let Some(ds) = &self.velocity {
            append_vectors(ds, start * nodes, &b.velocity)?;
        }
        append_rows(&self.force, start * members, &b.force)?;
        if let Some(ds) = &self.viscous {
            append_rows(ds, start * members, &b.viscous)?;
        }
        let steps = start as i64..(start + count) as i64;
        let zeros = vec![0_i64; count];
        let node_blocks: Vec<i64> = steps.clone().map(|s| s * nodes as i64).collect();
        let member_blocks: Vec<i64> = steps.map(|s| s * members as i64).collect();
        let [parts_at, parts, point_at, cell_at, connectivity_at, strut_at] = &self.offsets;
        for ds in [parts_at, cell_at, connectivity_at, strut_at] {
            append_rows(ds, start, &zeros)?;
        }
        append_rows(parts, start, &vec![1_i64; count])?;
        append_rows(point_at, start, &node_blocks)?;
        let point_data = self.steps.group("PointDataOffsets")?;
        for name in ["displacement", "velocity"].iter().take(1 + usize::from(self.velocity.is_some())) {
            append_rows(&point_data.dataset(name)?, start, &node_blocks)?;
        }
        let cell_data = self.steps.group("CellDataOffsets")?;
        for name in ["force", "viscous_force"].iter().take(1 + usize::from(self.viscous.is_some())) {
            append_rows(&cell_data.dataset(name)?, start, &member_blocks)?;
        }
        self.written += count;
        self.steps.attr("NSteps")?.write_scalar(&(self.written as i64))?;
        Ok(())
    }
}

/// An empty dataset of `width` columns (1: one-dimensional) that grows by rows, chunked
/// by `rows` rows.
fn growing<T: hdf5::H5Type>(group: &Group, name: &str, width: usize, rows: usize) -> Result<Dataset, Error> {
    let builder = group.new_dataset::<T>();
    Ok(if width == 1 {
        builder.chunk(vec![rows]).shape(vec![hdf5::Extent::resizable(0)]).create(name)?
    } else {
        builder
            .chunk(vec![rows, width])
            .shape(vec![hdf5::Extent::resizable(0), width.into()])
            .create(name)?
    })
}

/// Appends rows of 3 values (`values` flat) at row `start` of the (n, 3) dataset `ds`.
fn append_vectors(ds: &Dataset, start: usize, values: &[f64]) -> Result<(), Error> {
    let rows = values.len() / 3;
    ds.resize(vec![start + rows, 3])?;
    let view = ndarray::ArrayView2::from_shape((rows, 3), values)?;
    Ok(ds.write_slice(view, (start..start + rows, ..))?)
}

impl Recorder for ParaviewRecorder {
    fn model(&mut self, r: &ModelRecord) -> RecordResult {
        self.nodes = r.model.node_count();
        self.members = r.model.members.iter().map(|m| m.nodes).collect();
        self.struts = r.model.members.iter().map(|m| i8::from(m.kind == MemberKind::Strut)).collect();
        Ok(())
    }

    fn begin_stage(&mut self, stage: &Stage, _: &Constraints) -> RecordResult {
        self.stage = Some(self.open(stage)?);
        Ok(())
    }

    fn frame(&mut self, f: &Frame) -> RecordResult {
        let nodes = self.nodes;
        match &mut self.stage {
            Some(s) => s.push(f, nodes).map_err(|e| format!("{}: {e}", s.path.display()).into()),
            None => Ok(()),
        }
    }

    fn end_stage(&mut self, _: &Stage) -> RecordResult {
        let nodes = self.nodes;
        match self.stage.take() {
            Some(mut s) => s.flush(nodes).map_err(|e| format!("{}: {e}", s.path.display()).into()),
            None => Ok(()),
        }
    }
}
