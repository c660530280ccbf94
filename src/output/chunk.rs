//! HDF5 chunks filtered by tsim itself: byte shuffle, then a zlib stream, exactly what
//! HDF5's `shuffle` and `deflate` filters decode, so any HDF5 reader reads the chunks that
//! [`ChunkEncoder`] makes and `H5Dwrite_chunk` stores.
//!
//! Why not let HDF5 filter: its deflate filter runs the system zlib, which took 85 % of the
//! HDF5 writer thread's CPU on the paper case, more than the whole solver once the solver
//! reused factorizations. With zlib-rs (same format, level 1) the writer thread needs
//! 2.5× less CPU (0.43 → 0.17 s for the paper case) for files 7 % larger; the data are
//! bit-identical (bench/outputs.md, `perf` per thread).
//!
//! Why not deflate every byte: after the shuffle, byte k of every value is contiguous, a
//! *plane*. The high planes of a float (sign, exponent, leading mantissa bits) repeat from
//! step to step and deflate to a few percent; the low mantissa planes are noise, which
//! zlib-rs's level 1 (static Huffman codes) cannot shrink, yet they took most of its time.
//! So each plane is probed: its first [`PROBE`] bytes are deflated, and a plane that shrinks
//! to at most [`PAYS`] of that is deflated whole; any other is written as deflate *stored*
//! blocks (RFC 1951 §3.2.4: a copy, 5 bytes of header per 64 KiB). Deflate streams may mix
//! both kinds of block, so the chunk is still one zlib stream of HDF5's deflate filter
//! (RFC 1950: header, blocks, Adler-32), read by every inflater; on the paper case
//! deflate's share of the CPU samples fell from 17 % to about 2 %, and the file came out
//! 0.4 % smaller (bench/outputs.md).

use flate2::{Compress, Compression, FlushCompress, Status};

/// Bytes of a plane deflated to decide whether the whole plane pays: enough to see a
/// float's repeats from step to step (a paper-case step is 60 values), a few percent of a
/// 1 MiB chunk's plane.
const PROBE: usize = 1024;
/// A plane is deflated when its probe shrinks to at most this fraction. On the paper case
/// (per plane, zlib level 1) the noise planes shrink to 0.93 at best, and only with
/// zlib's dynamic codes, which zlib-rs's level 1 does not use; the planes that pay come out
/// at 0.01 to 0.4, or 0.7 to 0.9 for a plane half exponent, half noise.
const PAYS: f64 = 0.9;
/// Most bytes in one stored block (its LEN field has 16 bits).
const STORED_MAX: usize = 0xffff;

/// Reusable buffers and deflate state: encoding a chunk allocates nothing once the
/// buffers have grown to a chunk's size.
pub struct ChunkEncoder {
    /// Raw deflate (no zlib header): the zlib framing is written here, around the planes.
    deflate: Compress,
    shuffled: Vec<u8>,
    encoded: Vec<u8>,
}

impl ChunkEncoder {
    pub fn new(level: u32) -> Self {
        ChunkEncoder {
            deflate: Compress::new(Compression::new(level), false),
            shuffled: Vec::new(),
            encoded: Vec::new(),
        }
    }

    /// Encodes the chunk of `values` (native f64, padded with zeros to `len` elements, the
    /// chunk's full size): byte k of element i goes to position k·len + i, then each plane
    /// (the `len` bytes of one k) is deflated or stored, in one zlib stream.
    pub fn encode(&mut self, values: &[f64], len: usize) -> Result<&[u8], flate2::CompressError> {
        assert!(values.len() <= len, "a chunk holds at most its length");
        self.shuffled.clear();
        self.shuffled.resize(8 * len, 0);
        // Plane by plane: sequential writes, without an index check per byte.
        for (k, plane) in self.shuffled.chunks_exact_mut(len.max(1)).enumerate() {
            for (byte, v) in plane.iter_mut().zip(values) {
                *byte = v.to_ne_bytes()[k];
            }
        }
        self.encoded.clear();
        // CMF 0x78: deflate with a 32 KiB window; FLG 0x01: no dictionary, and the check
        // bits that make 0x7801 a multiple of 31 (RFC 1950 §2.2).
        self.encoded.extend_from_slice(&[0x78, 0x01]);
        for k in 0..8 {
            let plane = k * len..(k + 1) * len;
            if !self.deflate_if_it_pays(plane.clone())? {
                store(&mut self.encoded, &self.shuffled[plane]);
            }
        }
        // The last block: empty, stored, marked final.
        self.encoded.extend_from_slice(&[0x01, 0x00, 0x00, 0xff, 0xff]);
        let adler = zlib_rs::adler32::adler32(1, &self.shuffled);
        self.encoded.extend_from_slice(&adler.to_be_bytes());
        Ok(&self.encoded)
    }

    /// Deflates the probe of `self.shuffled[plane]`, then the rest if the probe paid; says
    /// whether it did (if not, nothing was written).
    fn deflate_if_it_pays(&mut self, plane: std::ops::Range<usize>) -> Result<bool, flate2::CompressError> {
        let start = self.encoded.len();
        let probe = plane.start + PROBE.min(plane.len());
        self.deflate.reset();
        self.deflate_flushed(plane.start..probe)?;
        let pays = (self.encoded.len() - start) as f64 <= PAYS * (probe - plane.start) as f64;
        if pays {
            self.deflate_flushed(probe..plane.end)?;
        } else {
            self.encoded.truncate(start);
        }
        Ok(pays)
    }

    /// Deflates `self.shuffled[range]` onto `self.encoded`, ending on a byte boundary with
    /// no final block (a sync flush), so that stored blocks or another stream may follow.
    fn deflate_flushed(&mut self, range: std::ops::Range<usize>) -> Result<(), flate2::CompressError> {
        if range.is_empty() {
            return Ok(());
        }
        let input = &self.shuffled[range];
        let before = self.deflate.total_in();
        loop {
            // compress_vec writes into spare capacity only; the flush is complete once a
            // call leaves some of it unused.
            self.encoded.reserve(input.len() / 4 + 64);
            let consumed = (self.deflate.total_in() - before) as usize;
            let status = self
                .deflate
                .compress_vec(&input[consumed..], &mut self.encoded, FlushCompress::Sync)?;
            let consumed = (self.deflate.total_in() - before) as usize;
            if status == Status::BufError || (consumed == input.len() && self.encoded.len() < self.encoded.capacity()) {
                return Ok(());
            }
        }
    }
}

/// Appends `data` as non-final stored blocks (RFC 1951 §3.2.4): each a header byte
/// (BFINAL 0, BTYPE 00, byte-aligned), LEN and its complement, then LEN bytes.
fn store(out: &mut Vec<u8>, data: &[u8]) {
    for block in data.chunks(STORED_MAX) {
        let n = block.len() as u16;
        out.push(0x00);
        out.extend_from_slice(&n.to_le_bytes());
        out.extend_from_slice(&(!n).to_le_bytes());
        out.extend_from_slice(block);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::{Decompress, FlushDecompress};

    /// Inverse of the filter pipeline, written from HDF5's definition of the two filters:
    /// the whole chunk is one zlib stream (checked: it ends, and the Adler-32 matches).
    fn decode(bytes: &[u8], len: usize) -> Vec<f64> {
        let mut shuffled = Vec::with_capacity(8 * len);
        let mut inflate = Decompress::new(true);
        let status = inflate.decompress_vec(bytes, &mut shuffled, FlushDecompress::Finish).unwrap();
        assert_eq!(status, Status::StreamEnd);
        assert_eq!(inflate.total_in() as usize, bytes.len(), "nothing after the stream");
        assert_eq!(shuffled.len(), 8 * len);
        (0..len)
            .map(|i| f64::from_ne_bytes(std::array::from_fn(|k| shuffled[k * len + i])))
            .collect()
    }

    /// Values in [1, 1 + 2⁻⁴) whose low 48 mantissa bits are noise (xorshift64): six noise
    /// planes, and two constant ones (sign, exponent and the top 4 mantissa bits).
    fn noise(n: usize) -> Vec<f64> {
        let mut s = 0x9e37_79b9_7f4a_7c15_u64;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                1.0 + (s >> 16) as f64 / (1u64 << 52) as f64
            })
            .collect()
    }

    #[test]
    fn chunks_round_trip_with_zero_padding() {
        let mut enc = ChunkEncoder::new(1);
        // Empty, smaller than a probe, larger than a stored block (70 000 > 65 535 bytes a
        // plane), and padded.
        for (n, len) in [(0, 4), (5, 8), (1000, 1000), (999, 1024), (70_000, 70_000)] {
            let values: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() * 1e3 + i as f64).collect();
            let bytes = enc.encode(&values, len).unwrap().to_vec();
            let back = decode(&bytes, len);
            assert_eq!(&back[..n], &values[..]);
            assert!(back[n..].iter().all(|&v| v == 0.0));
        }
    }

    /// Noise in the mantissa is stored (the chunk is its size plus framing, within 2 %),
    /// while the exponent planes and a zero chunk deflate; both decode exactly.
    #[test]
    fn noise_planes_are_stored_and_the_rest_deflated() {
        let mut enc = ChunkEncoder::new(1);
        let n = 16_000;
        let values = noise(n);
        let bytes = enc.encode(&values, n).unwrap().to_vec();
        assert_eq!(decode(&bytes, n), values);
        // The six noise planes stored (deflate's static codes would grow them by about 5 %),
        // the two constant planes almost gone.
        let stored = 6 * n;
        assert!(
            bytes.len() >= stored && (bytes.len() as f64) < 1.02 * stored as f64,
            "{}",
            bytes.len()
        );
        let zeros = vec![0.0; n];
        let bytes = enc.encode(&zeros, n).unwrap().to_vec();
        assert!(bytes.len() < 8 * n / 50, "{}", bytes.len());
        assert_eq!(decode(&bytes, n), zeros);
    }
}
