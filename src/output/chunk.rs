//! HDF5 chunks filtered by tsim itself: byte shuffle, then zlib deflate, exactly the
//! pipeline of HDF5's `shuffle` and `deflate` filters, so any HDF5 reader decodes the
//! chunks that [`ChunkEncoder`] makes and `H5Dwrite_chunk` stores.
//!
//! Why not let HDF5 filter: its deflate filter runs the system zlib, which took 85 % of the
//! HDF5 writer thread's CPU on the paper case, more than the whole solver once the solver
//! reused factorizations. With zlib-rs (same format, level 1) the writer thread needs
//! 2.5× less CPU (0.43 → 0.17 s for the paper case) for files 7 % larger; the data are
//! bit-identical (bench/outputs.md, `perf` per thread).

use flate2::{Compress, Compression, FlushCompress, Status};

/// Reusable buffers and deflate state: encoding a chunk allocates nothing once the
/// buffers have grown to a chunk's size.
pub struct ChunkEncoder {
    deflate: Compress,
    shuffled: Vec<u8>,
    encoded: Vec<u8>,
}

impl ChunkEncoder {
    pub fn new(level: u32) -> Self {
        ChunkEncoder {
            // zlib header and Adler-32 trailer: the stream format of HDF5's deflate filter.
            deflate: Compress::new(Compression::new(level), true),
            shuffled: Vec::new(),
            encoded: Vec::new(),
        }
    }

    /// Encodes the chunk of `values` (native f64, padded with zeros to `len` elements, the
    /// chunk's full size): byte k of element i goes to position k·len + i, then deflate.
    pub fn encode(&mut self, values: &[f64], len: usize) -> Result<&[u8], flate2::CompressError> {
        assert!(values.len() <= len, "a chunk holds at most its length");
        self.shuffled.clear();
        self.shuffled.resize(8 * len, 0);
        for (i, v) in values.iter().enumerate() {
            for (k, byte) in v.to_ne_bytes().into_iter().enumerate() {
                self.shuffled[k * len + i] = byte;
            }
        }
        self.deflate.reset();
        self.encoded.clear();
        loop {
            // compress_vec writes into spare capacity only; grow it until the stream ends.
            self.encoded.reserve(self.shuffled.len() / 2 + 64);
            let consumed = self.deflate.total_in() as usize;
            if self
                .deflate
                .compress_vec(&self.shuffled[consumed..], &mut self.encoded, FlushCompress::Finish)?
                == Status::StreamEnd
            {
                return Ok(&self.encoded);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::{Decompress, FlushDecompress};

    /// Inverse of the filter pipeline, written from HDF5's definition of the two filters.
    fn decode(bytes: &[u8], len: usize) -> Vec<f64> {
        let mut shuffled = Vec::with_capacity(8 * len);
        let mut inflate = Decompress::new(true);
        let status = inflate.decompress_vec(bytes, &mut shuffled, FlushDecompress::Finish).unwrap();
        assert_eq!(status, Status::StreamEnd);
        assert_eq!(shuffled.len(), 8 * len);
        (0..len)
            .map(|i| f64::from_ne_bytes(std::array::from_fn(|k| shuffled[k * len + i])))
            .collect()
    }

    #[test]
    fn chunks_round_trip_with_zero_padding() {
        let mut enc = ChunkEncoder::new(1);
        for (n, len) in [(0, 4), (5, 8), (1000, 1000), (999, 1024)] {
            let values: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() * 1e3 + i as f64).collect();
            let bytes = enc.encode(&values, len).unwrap().to_vec();
            let back = decode(&bytes, len);
            assert_eq!(&back[..n], &values[..]);
            assert!(back[n..].iter().all(|&v| v == 0.0));
        }
    }
}
