//! The replay's protobuf by hand where the derive costs most: the member records of
//! `/tsim/members` and the scene's node markers, encoded once with only their numbers
//! patched per step, and the scene's lines; our own topics' messages (`msg`).

use super::scene::{state_colour, CABLE_WIDTH, GOLD, GREEN, LEVELS, PURPLE, STRUT_WIDTH, SUPPORT_SIZE};
use foxglove::messages::{line_primitive, SceneEntity};
use foxglove::Encode;
use nalgebra::Vector3;

/// The repeated `members` field (number 3) of `msg::MemberForces`, encoded once: per
/// member the record {1: id, 2: force}, whose only changing bytes are the force's eight.
/// Patching eight bytes per member costs far less than encoding the records through the
/// derive at every step (bench/outputs.md) and gives the same bytes (tested).
#[derive(Default)]
pub(super) struct MemberRecords {
    bytes: Vec<u8>,
    /// Where each member's little-endian force starts in `bytes`.
    force_at: Vec<usize>,
}

impl MemberRecords {
    pub(super) fn new<'a>(ids: impl Iterator<Item = &'a str>) -> Self {
        let mut r = MemberRecords::default();
        for id in ids {
            // Field 1 (id): tag 0x0a, length, bytes; field 2 (force, 64-bit): tag 0x11, 8 bytes.
            let inner = 1 + varint_len(id.len()) + id.len() + 1 + 8;
            r.bytes.push(0x1a); // field 3, length-delimited
            put_varint(&mut r.bytes, inner);
            r.bytes.push(0x0a);
            put_varint(&mut r.bytes, id.len());
            r.bytes.extend_from_slice(id.as_bytes());
            r.bytes.push(0x11);
            r.force_at.push(r.bytes.len());
            r.bytes.extend_from_slice(&[0; 8]);
        }
        r
    }

    pub(super) fn with_forces(&mut self, forces: &[f64]) -> &[u8] {
        for (&at, force) in self.force_at.iter().zip(forces) {
            self.bytes[at..at + 8].copy_from_slice(&force.to_le_bytes());
        }
        &self.bytes
    }
}

fn varint_len(mut v: usize) -> usize {
    let mut n = 1;
    while v >= 0x80 {
        v >>= 7;
        n += 1;
    }
    n
}

pub(super) fn put_varint(out: &mut Vec<u8>, mut v: usize) {
    while v >= 0x80 {
        out.push((v as u8 & 0x7f) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// The scene's node markers, encoded once as the `cubes` (field 8: supported nodes) and
/// `spheres` (field 9: the others) of the `tensegrity` entity: per node a record {1: pose
/// {1: position {x, y, z}, 2: orientation {w = 1}}, 2: size, 3: colour} whose only changing
/// bytes are the position's 24. Written between the entity's head (fields 1–3) and its
/// lines and texts (fields 11, 13), they give the bytes prost encodes for the whole entity
/// (tested), except that a zero coordinate is written rather than left out (it decodes the
/// same).
#[derive(Default)]
pub(super) struct NodeRecords {
    pub(super) bytes: Vec<u8>,
    /// Where each node's x starts in `bytes` (y at +9, z at +18), by node index.
    position_at: Vec<usize>,
}

impl NodeRecords {
    /// `supports[n]`: the number of supported directions of node n; `diameter`: of the
    /// spheres [m].
    pub(super) fn new(supports: &[usize], diameter: f64) -> Self {
        let mut r = NodeRecords {
            bytes: Vec::new(),
            position_at: vec![0; supports.len()],
        };
        let edge = SUPPORT_SIZE * diameter;
        for cubes in [true, false] {
            for (n, &fixed) in supports.iter().enumerate() {
                if (fixed > 0) != cubes {
                    continue;
                }
                let (size, colour) = match fixed {
                    0 => (diameter, GOLD),
                    3 => (edge, GREEN),
                    _ => (edge, PURPLE),
                };
                let mut size_bytes = Vec::new();
                for (field, v) in [(1, size), (2, size), (3, size)] {
                    put_double(&mut size_bytes, field, v);
                }
                let mut colour_bytes = Vec::new();
                for (field, v) in [(1, colour.r), (2, colour.g), (3, colour.b), (4, colour.a)] {
                    put_double(&mut colour_bytes, field, v);
                }
                // Pose: position (3 × (tag + 8 bytes) = 27 bytes), orientation {4: w} (9).
                let body = 2 + 40 + 2 + size_bytes.len() + 2 + colour_bytes.len();
                r.bytes.push(if cubes { 0x42 } else { 0x4a });
                put_varint(&mut r.bytes, body);
                r.bytes.extend_from_slice(&[0x0a, 40, 0x0a, 27]);
                r.position_at[n] = r.bytes.len() + 1;
                for tag in [0x09, 0x11, 0x19] {
                    r.bytes.push(tag);
                    r.bytes.extend_from_slice(&[0; 8]);
                }
                r.bytes.extend_from_slice(&[0x12, 9, 0x21]);
                r.bytes.extend_from_slice(&1.0_f64.to_le_bytes());
                r.bytes.push(0x12);
                put_varint(&mut r.bytes, size_bytes.len());
                r.bytes.extend_from_slice(&size_bytes);
                r.bytes.push(0x1a);
                put_varint(&mut r.bytes, colour_bytes.len());
                r.bytes.extend_from_slice(&colour_bytes);
            }
        }
        r
    }

    /// Node `n`'s position as an encoded `Point3` {1: x, 2: y, 3: z} (27 bytes), as last
    /// patched.
    fn point(&self, n: usize) -> &[u8] {
        let at = self.position_at[n] - 1;
        &self.bytes[at..at + 27]
    }

    pub(super) fn set_positions(&mut self, positions: &[Vector3<f64>]) {
        for (&at, p) in self.position_at.iter().zip(positions) {
            for (k, v) in [p.x, p.y, p.z].into_iter().enumerate() {
                let at = at + 9 * k;
                self.bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
            }
        }
    }
}

/// A protobuf `double` field, left out when zero (as prost does).
fn put_double(out: &mut Vec<u8>, field: u8, v: f64) {
    if v != 0.0 {
        out.push(field << 3 | 1);
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// The scene entity's `lines` (field 11), encoded as prost encodes them: for each
/// non-empty bucket of `buckets` (struts then cables, each by colour state, see
/// [`state_colour`]) one `LinePrimitive` {1: type, 3: thickness, 4: scale_invariant,
/// 5: points, 6: colour}, each point the 27 bytes of its node's position in `nodes`.
/// Cheaper than building the points and encoding them through prost (bench/outputs.md).
/// Empties the buckets.
pub(super) fn encode_lines(out: &mut Vec<u8>, buckets: &mut [Vec<usize>], nodes: &NodeRecords) {
    let states = 1 + 2 * LEVELS;
    for (bucket, ends) in buckets.iter_mut().enumerate().filter(|(_, e)| !e.is_empty()) {
        let thickness = if bucket < states { STRUT_WIDTH } else { CABLE_WIDTH };
        let c = state_colour(bucket % states);
        let colour = [c.r, c.g, c.b, c.a];
        let colour_len = 9 * colour.iter().filter(|&&v| v != 0.0).count();
        out.push(0x5a);
        put_varint(out, 2 + 9 + 2 + 29 * ends.len() + 2 + colour_len);
        out.extend_from_slice(&[0x08, line_primitive::Type::LineList as u8, 0x19]);
        out.extend_from_slice(&thickness.to_le_bytes());
        out.extend_from_slice(&[0x20, 0x01]);
        for &n in ends.iter() {
            out.extend_from_slice(&[0x2a, 27]);
            out.extend_from_slice(nodes.point(n));
        }
        out.extend_from_slice(&[0x32, colour_len as u8]);
        for (field, v) in (1..).zip(colour) {
            put_double(out, field, v);
        }
        ends.clear();
    }
}

/// Messages of our own topics. The derive names each schema `<lowercase>.<Name>`.
pub(super) mod msg {
    #[derive(foxglove::Encode)]
    pub struct Energy {
        pub stage: String,
        pub step: u64,
        pub kinetic: f64,
        pub strain: f64,
        pub damping: f64,
        pub external: f64,
        /// Work done on the members by changing their rest lengths (actuation).
        pub actuation: f64,
        /// kinetic + strain + contact + damping − external − actuation: the energy balance, constant
        /// while the integration conserves energy.
        pub total: f64,
    }

    #[derive(foxglove::Encode)]
    pub struct MemberForce {
        pub id: String,
        pub force: f64,
    }

    #[derive(foxglove::Encode, Default)]
    pub struct MemberForces {
        pub stage: String,
        pub step: u64,
        pub members: Vec<MemberForce>,
    }

    #[derive(foxglove::Encode)]
    pub struct StageStart {
        pub name: String,
    }

    #[derive(foxglove::Encode)]
    pub struct PulleySlide {
        /// The pulley's node id.
        pub node: String,
        /// Rest length run over it towards the cable's first member [m].
        pub slide: f64,
    }

    #[derive(foxglove::Encode)]
    pub struct Cable {
        pub id: String,
        /// The cable's tension (with friction, its largest span's) [N].
        pub tension: f64,
        pub pulleys: Vec<PulleySlide>,
    }

    #[derive(foxglove::Encode, Default)]
    pub struct Cables {
        pub stage: String,
        pub step: u64,
        pub cables: Vec<Cable>,
    }
}

pub(super) fn prost_len(entity: &SceneEntity) -> usize {
    entity.encoded_len().expect("prost messages know their length")
}
