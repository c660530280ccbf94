//! The netCDF-4 toolkit of the HDF5 writers: datasets attached to dimension scales with
//! units and long names, chunked appends through the chunk encoder, whole-dataset writes
//! with one transfer buffer, string attributes.

use super::{Error, GZIP_LEVEL};
use crate::output::chunk::ChunkEncoder;
use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, File, FileBuilder, Group, H5Type, Location};
use hdf5_sys::h5::{herr_t, hsize_t};
use hdf5_sys::h5d::H5Dwrite;
use hdf5_sys::h5i::hid_t;
use hdf5_sys::h5p::{H5Pclose, H5Pcreate, H5Pset_buffer, H5P_CLS_DATASET_XFER};
use hdf5_sys::h5s::H5S_ALL;
use nalgebra::Vector3;
use std::ffi::{c_char, c_uint, CString};

// The high-level dimension-scale API (libhdf5_hl, linked by hdf5-sys's `hl` feature), which
// neither hdf5-metno nor its -sys crate binds.
extern "C" {
    fn H5DSset_scale(dsid: hid_t, dimname: *const c_char) -> herr_t;
    fn H5DSattach_scale(did: hid_t, dsid: hid_t, idx: c_uint) -> herr_t;
}

/// Rows per chunk of a clearance event table (events are rare; a chunk is 0.5–1 KiB).
const EVENT_CHUNK: usize = 64;

/// An empty dataset growing along its first axis, `width` values per row (1: a 1-D one).
pub(super) fn extendable<T: H5Type>(group: &Group, name: &str, width: usize) -> Result<Dataset, Error> {
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
pub(in crate::output) fn append_rows<T: H5Type>(ds: &Dataset, start: usize, values: &[T]) -> Result<(), Error> {
    ds.resize(vec![start + values.len()])?;
    Ok(ds.write_slice(values, start..start + values.len())?)
}

/// Creates datasets in one group and attaches them to the group's dimension scales.
pub(crate) struct Dims {
    pub(crate) group: Group,
    scales: Vec<(String, Dataset)>,
}

impl Dims {
    pub(crate) fn new(group: Group) -> Self {
        Dims { group, scales: Vec::new() }
    }

    /// A coordinate variable: a 1-D dataset that is the dimension scale of its own name.
    pub(crate) fn coord<T: H5Type>(&mut self, name: &str, values: &[T], units: &str, long_name: &str) -> Result<(), Error> {
        let ds = self.group.new_dataset::<T>().shape(values.len()).create(name)?;
        write_whole(&ds, values)?;
        describe(&ds, units, long_name)?;
        self.scale(name, ds)
    }

    pub(crate) fn labels<S: AsRef<str>>(&mut self, name: &str, labels: &[S], long_name: &str) -> Result<(), Error> {
        self.coord(name, &varlen(labels)?, "1", long_name)
    }

    /// Makes `ds` the dimension scale `name` of this group.
    pub(super) fn scale(&mut self, name: &str, ds: Dataset) -> Result<(), Error> {
        let c_name = CString::new(name)?;
        {
            let _lock = hdf5_sys::LOCK.lock();
            // SAFETY: `ds` is an open dataset and `c_name` outlives the call.
            check(unsafe { H5DSset_scale(ds.id(), c_name.as_ptr()) }, "H5DSset_scale")?;
        }
        self.scales.push((name.into(), ds));
        Ok(())
    }

    pub(super) fn find(&self, dim: &str) -> Result<&Dataset, Error> {
        Ok(&self
            .scales
            .iter()
            .find(|(n, _)| n == dim)
            .ok_or_else(|| format!("HDF5: no dimension {dim}"))?
            .1)
    }

    pub(super) fn attach(&self, ds: &Dataset, dims: &[&str]) -> Result<(), Error> {
        for (axis, dim) in dims.iter().enumerate() {
            let scale = self.find(dim)?;
            let _lock = hdf5_sys::LOCK.lock();
            // SAFETY: both ids are open datasets of the same file.
            check(unsafe { H5DSattach_scale(ds.id(), scale.id(), axis as c_uint) }, "H5DSattach_scale")?;
        }
        Ok(())
    }

    pub(super) fn sizes(&self, dims: &[&str]) -> Result<Vec<usize>, Error> {
        dims.iter().map(|d| Ok(self.find(d)?.size())).collect()
    }

    /// A fixed-size variable written at once; `values` in row-major order over `dims`.
    pub(crate) fn var<T: H5Type>(&self, name: &str, dims: &[&str], values: &[T], units: &str, long_name: &str) -> Result<(), Error> {
        let ds = self.group.new_dataset::<T>().shape(self.sizes(dims)?).create(name)?;
        write_whole(&ds, values)?;
        describe(&ds, units, long_name)?;
        self.attach(&ds, dims)
    }

    /// A variable over (time, `dims`...) growing along time, chunked `chunk` steps deep, with
    /// shuffle + gzip; attached to the `time` scale once that exists.
    pub(super) fn streamed(&self, name: &str, dims: &[&str], chunk: usize, units: &str, long_name: &str) -> Result<Dataset, Error> {
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
pub(super) fn append_chunk(
    ds: &Dataset,
    start: usize,
    rows: usize,
    chunk: usize,
    values: &[f64],
    encoder: &mut ChunkEncoder,
) -> Result<(), Error> {
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

pub(super) fn write_whole<T: H5Type>(ds: &Dataset, values: &[T]) -> Result<(), Error> {
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

pub(super) fn check(err: herr_t, what: &str) -> Result<(), Error> {
    if err < 0 {
        return Err(format!("HDF5: {what} failed").into());
    }
    Ok(())
}

pub(super) fn describe(ds: &Dataset, units: &str, long_name: &str) -> Result<(), Error> {
    str_attr(ds, "units", units)?;
    str_attr(ds, "long_name", long_name)
}

/// A new file's builder whose groups carry no timestamps (datasets carry none already:
/// hdf5-metno's default, as h5py's). Two runs of a case then write the same bytes, so the
/// CRC in outcome.json compares results, not the second each file was written in.
pub(crate) fn untimed_file() -> FileBuilder {
    let mut builder = File::with_options();
    builder.with_fcpl(|p| p.obj_track_times(false));
    builder
}

/// `parent/name`, a group without timestamps (see [`untimed_file`]).
pub(crate) fn untimed_group(parent: &Group, name: &str) -> Result<Group, Error> {
    Ok(parent.create_group_builder().obj_track_times(false).create(name)?)
}

pub(crate) fn str_attr(loc: &Location, name: &str, value: &str) -> Result<(), Error> {
    loc.new_attr::<VarLenUnicode>()
        .create(name)?
        .write_scalar(&value.parse::<VarLenUnicode>()?)?;
    Ok(())
}

pub(crate) fn varlen<S: AsRef<str>>(values: &[S]) -> Result<Vec<VarLenUnicode>, Error> {
    values.iter().map(|s| Ok(s.as_ref().parse()?)).collect()
}

/// Appends the vectors' components: three-value copies, where a flattening iterator, of
/// unknown length, cost the writer 3 % of its time on the paper case (perf).
pub(super) fn extend_vectors(buf: &mut Vec<f64>, v: &[Vector3<f64>]) {
    buf.reserve(3 * v.len());
    for p in v {
        buf.extend_from_slice(p.as_slice());
    }
}

pub(super) fn flat(v: &[Vector3<f64>]) -> Vec<f64> {
    v.iter().flat_map(|p| p.iter().copied()).collect()
}
