//! `replay.mcap`: every stage of a case on one timeline for Foxglove (issue 4 is the
//! contract; topic names and Foxglove schema names must not change).
//!
//! Topics (protobuf, zstd-compressed chunks):
//! - `/tsim/scene` (`foxglove.SceneUpdate`): one entity `tensegrity` in frame `world`:
//!   struts and cables as `LINE_LIST` primitives coloured by force (tension grey-red to full
//!   red, compression grey-blue to full blue, each scale topped by the step's largest force
//!   of its sign; slack grey), a sphere at every free node, a cube at every supported one, and a
//!   legend text with the scales' maxima. When the closest pair of non-adjacent struts is
//!   within [`NEAR_RADII`] times the larger radius, its struts are drawn again twice as
//!   thick in magenta with the link between their closest points, and the legend names
//!   them with their clearance.
//! - `/tsim/energy` (`energy.Energy`): kinetic, strain, damping, external and total energy.
//! - `/tsim/members` (`memberforces.MemberForces`): every member's id and force; in a Plot
//!   panel, `/tsim/members.members[:]{id=="strut0_0"}.force`.
//! - `/tsim/stage` (`stagestart.StageStart`): one message at the start of each stage.
//!
//! Scene, energy and members are logged together at every recorded step of a time-stepping
//! stage, thinned to `outputs.replay_rate` frames per simulated second (its first and last
//! steps always kept: [`McapRecorder::create`]); form-finding logs one scene and one members message (its equilibrium; it has no
//! energy ledger). A metadata record `case` (case id, tsim version) opens the file and one
//! named `status` ("complete" or "failed: <reason>") closes it; a killed process leaves a
//! file with neither that record nor an MCAP footer.
//!
//! # Timeline
//! Log time is simulated time [s] from 0, stages placed back to back in the order they run:
//! - a static stage occupies [`STATIC_STEP`] per step: form-finding one step (its
//!   equilibrium), eigen analysis one step (its stage message only), folding one step per
//!   load step (log time = stage start + step × `STATIC_STEP`, the applied fraction being in
//!   the HDF5 output);
//! - a dynamic stage logs its frame at stage start + frame time;
//! - each stage starts one step after the previous one's last step, a step being the
//!   increment between that stage's last two recorded frames (its time step, times the
//!   output stride `every` unless the last step falls between strides; `STATIC_STEP` for
//!   static stages).
//!
//! Log times are strictly increasing on every topic: a computed time that does not exceed
//! the previous one is moved 1 ns past it.

use crate::model::{MemberKind, Model};
use crate::record::{Energy, FormFindRecord, Frame, ModelRecord, Nearest, Outcome, RecordResult, Recorder, Stage};
use foxglove::messages::{
    line_primitive, Color, LinePrimitive, Point3, Pose, Quaternion, SceneEntity, SceneUpdate, TextPrimitive, Timestamp,
};
use foxglove::Encode;
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

type Error = Box<dyn std::error::Error + Send + Sync>;

/// zstd level of the MCAP chunks (see [`McapRecorder::create`]).
const ZSTD_LEVEL: i32 = -3;
/// Synthetic duration of one step of a static stage on the log timeline [s].
pub const STATIC_STEP: f64 = 0.1;
/// Line widths [px], independent of zoom so that any model size reads well.
const STRUT_WIDTH: f64 = 6.0;
const CABLE_WIDTH: f64 = 2.0;
/// A member whose |force| is below this fraction of the step's largest |force| is slack.
const SLACK_FRACTION: f64 = 1e-6;
/// Shades of each force scale: a member's shade is ⌈LEVELS · |N| / max |N|⌉, the maximum
/// taken over the step's members of the same sign.
const LEVELS: usize = 4;
/// Node sphere diameter as a fraction of the median member length of the model.
const NODE_SIZE: f64 = 0.05;
/// Support cube edge as a multiple of the node sphere diameter.
const SUPPORT_SIZE: f64 = 1.6;
/// The closest strut pair is highlighted when its clearance is below this many times the
/// larger of the two radii: about to touch, on the scale of the struts themselves.
pub const NEAR_RADII: f64 = 2.0;
/// Highlighted struts: a magenta apart from the force scales, node and support colours.
const MAGENTA: Color = Color {
    r: 0.85,
    g: 0.0,
    b: 0.75,
    a: 1.0,
};
/// Legend font height [px].
const LEGEND_FONT: f64 = 14.0;
const RED: Color = Color {
    r: 0.85,
    g: 0.10,
    b: 0.10,
    a: 1.0,
};
const BLUE: Color = Color {
    r: 0.10,
    g: 0.30,
    b: 0.90,
    a: 1.0,
};
/// Slack members, and where the force scales start: a mid grey, so that a faint force is
/// still seen on Foxglove's light theme (a pale tint of white was not).
const GREY: Color = Color {
    r: 0.55,
    g: 0.55,
    b: 0.55,
    a: 1.0,
};
const GOLD: Color = Color {
    r: 0.95,
    g: 0.70,
    b: 0.10,
    a: 1.0,
};
const GREEN: Color = Color {
    r: 0.10,
    g: 0.65,
    b: 0.25,
    a: 1.0,
};
const PURPLE: Color = Color {
    r: 0.60,
    g: 0.30,
    b: 0.80,
    a: 1.0,
};
/// Legend text: a teal of relative luminance 0.18, 4.6:1 against both black and white
/// (WCAG's 4.5:1 for text), readable on Foxglove's dark and light themes alike (white
/// text vanished on the light one).
const TEXT: Color = Color {
    r: 0.0,
    g: 0.515,
    b: 0.515,
    a: 1.0,
};

/// Colour of a line state: 0 slack (grey), 1..=LEVELS tension (grey-red to full red),
/// LEVELS+1..=2·LEVELS compression (grey-blue to full blue).
fn state_colour(state: usize) -> Color {
    if state == 0 {
        return GREY;
    }
    let (full, level) = if state <= LEVELS { (RED, state) } else { (BLUE, state - LEVELS) };
    let s = level as f64 / LEVELS as f64;
    let mix = |w: f64, c: f64| s * c + (1.0 - s) * w;
    Color {
        r: mix(GREY.r, full.r),
        g: mix(GREY.g, full.g),
        b: mix(GREY.b, full.b),
        a: 1.0,
    }
}

/// The shade of |force| on a scale whose top is `max` (> 0): 1..=LEVELS.
fn level(force: f64, max: f64) -> usize {
    ((LEVELS as f64 * force.abs() / max).ceil() as usize).clamp(1, LEVELS)
}

/// `x` with three significant digits, plainly where that reads well.
fn sig3(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || !a.is_finite() {
        format!("{x}")
    } else if (1e-2..1e5).contains(&a) {
        let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.2e}")
    }
}

/// The repeated `members` field (number 3) of `msg::MemberForces`, encoded once: per
/// member the record {1: id, 2: force}, whose only changing bytes are the force's eight.
/// Encoding the 50 records per step through the derive cost twice as much CPU as encoding
/// the whole scene (perf); patching eight bytes per member gives the same bytes (tested).
#[derive(Default)]
struct MemberRecords {
    bytes: Vec<u8>,
    /// Where each member's little-endian force starts in `bytes`.
    force_at: Vec<usize>,
}

impl MemberRecords {
    fn new<'a>(ids: impl Iterator<Item = &'a str>) -> Self {
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

    fn with_forces(&mut self, forces: &[f64]) -> &[u8] {
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

fn put_varint(out: &mut Vec<u8>, mut v: usize) {
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
struct NodeRecords {
    bytes: Vec<u8>,
    /// Where each node's x starts in `bytes` (y at +9, z at +18), by node index.
    position_at: Vec<usize>,
}

impl NodeRecords {
    /// `supports[n]`: the number of supported directions of node n; `diameter`: of the
    /// spheres [m].
    fn new(supports: &[usize], diameter: f64) -> Self {
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

    fn set_positions(&mut self, positions: &[Vector3<f64>]) {
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
/// Building the points and encoding them through prost took 9 % of the writer's time on
/// the paper case, this 2 % (perf).
/// Empties the buckets.
fn encode_lines(out: &mut Vec<u8>, buckets: &mut [Vec<usize>], nodes: &NodeRecords) {
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
mod msg {
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
        /// kinetic + strain + damping − external − actuation: the energy balance, constant
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
}

/// Streams a case to MCAP.
pub struct McapRecorder {
    /// `None` once finished.
    writer: Option<mcap::Writer<BufWriter<File>>>,
    channels: Channels,
    clock: Clock,
    /// Ends and kind of each member.
    members: Vec<([usize; 2], MemberKind)>,
    member_ids: Vec<String>,
    /// The closest strut pair of the state being logged, when the frame has one.
    nearest: Option<Nearest>,
    /// The `/tsim/members` message's member records, encoded once.
    member_records: MemberRecords,
    /// The end nodes of the scene's lines, one list per (kind, state), reused between steps.
    buckets: Vec<Vec<usize>>,
    /// The scene's lines, encoded (see [`encode_lines`]).
    lines: Vec<u8>,
    /// The node spheres and support cubes, encoded once.
    nodes: NodeRecords,
    /// Node sphere diameter [m].
    node_size: f64,
    /// Where the legend stands: above the first state logged, for the whole case.
    legend_at: Option<Vector3<f64>>,
    /// The legend's lines that do not change (nodes and supports).
    legend_key: String,
    stage: Option<Stage>,
    buf: Vec<u8>,
    /// Shortest simulated time between two frames logged in a time-stepping stage [s]
    /// (`1 / outputs.replay_rate`; 0: every frame given).
    min_interval: f64,
    /// Stage time of the stage's last logged frame [s].
    logged_at: Option<f64>,
    /// The stage's latest frame when it was not logged (`holding`): logged at the stage's
    /// end, so that a replay always shows where a stage ends. Its buffers are reused.
    held: HeldFrame,
    holding: bool,
}

/// A frame kept for [`McapRecorder::end_stage`].
#[derive(Default)]
struct HeldFrame {
    step: usize,
    /// Log time [s].
    t: f64,
    positions: Vec<Vector3<f64>>,
    forces: Vec<f64>,
    energy: Energy,
    nearest: Option<Nearest>,
}

struct Channels {
    scene: u16,
    energy: u16,
    members: u16,
    stage: u16,
}

impl McapRecorder {
    /// Creates (truncates) `path`. The output stride is applied by the stages; of the
    /// frames given, a time-stepping stage logs its first, its last, and each one at least
    /// `1 / replay_rate` s of simulated time after the last logged one (every frame with
    /// `replay_rate` 0). Static stages log every frame.
    pub fn create(path: &Path, case_id: &str, replay_rate: f64) -> Result<Self, Error> {
        // zstd level −3, a "fast" level: level −1 gave as small a file as level 1 on the
        // paper case (20.7 MB either way, every frame) for 8 % less writer CPU, and −3 and
        // −5 a further 6 % and 9 % less for files 10 % and 13 % larger; lz4 cost as much
        // CPU as −1 for a file 46 % larger. With the replay thinned to 250 frames per
        // simulated second the file is 3.2 MB, and −3's CPU is worth its 10 % (bench/outputs.md).
        // mcap takes the level as a u32 and hands it to zstd as an i32, so −3 goes through
        // as its two's complement. Single-threaded: the recorder
        // has a thread of its own (see `Background`), and zstd's own workers would compete
        // with the solver.
        let options = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(ZSTD_LEVEL as u32)
            .compression_threads(0);
        let mut writer = options.create(BufWriter::new(File::create(path)?))?;
        let channels = Channels {
            scene: channel::<SceneUpdate>(&mut writer, "/tsim/scene")?,
            energy: channel::<msg::Energy>(&mut writer, "/tsim/energy")?,
            members: channel::<msg::MemberForces>(&mut writer, "/tsim/members")?,
            stage: channel::<msg::StageStart>(&mut writer, "/tsim/stage")?,
        };
        let case = BTreeMap::from([
            ("case_id".to_string(), case_id.to_string()),
            ("tsim_version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ]);
        writer.write_metadata(&mcap::records::Metadata {
            name: "case".into(),
            metadata: case,
        })?;
        Ok(McapRecorder {
            writer: Some(writer),
            channels,
            clock: Clock::default(),
            members: Vec::new(),
            member_ids: Vec::new(),
            nearest: None,
            member_records: MemberRecords::default(),
            buckets: vec![Vec::new(); 2 * (1 + 2 * LEVELS)],
            lines: Vec::new(),
            nodes: NodeRecords::default(),
            node_size: 0.0,
            legend_at: None,
            legend_key: String::new(),
            stage: None,
            buf: Vec::new(),
            min_interval: if replay_rate > 0.0 { 1.0 / replay_rate } else { 0.0 },
            logged_at: None,
            held: HeldFrame::default(),
            holding: false,
        })
    }

    fn log<T: Encode>(&mut self, channel: u16, log_time: u64, msg: &T) -> Result<(), Error> {
        self.buf.clear();
        msg.encode(&mut self.buf).map_err(|e| e.to_string())?;
        self.write_buf(channel, log_time)
    }

    /// Writes the encoded message in `self.buf` on `channel`.
    fn write_buf(&mut self, channel: u16, log_time: u64) -> Result<(), Error> {
        let writer = self.writer.as_mut().ok_or("MCAP recorder already finished")?;
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: 0,
            log_time,
            publish_time: log_time,
        };
        Ok(writer.write_to_known_channel(&header, &self.buf)?)
    }

    /// `/tsim/members`: the message head (stage, step) encoded as `msg::MemberForces`
    /// encodes it, then the member records with this step's forces patched in.
    fn log_members(&mut self, stage: &Stage, step: usize, ns: u64, forces: &[f64]) -> Result<(), Error> {
        self.buf.clear();
        let head = msg::MemberForces {
            stage: stage.name().into(),
            step: step as u64,
            members: Vec::new(),
        };
        head.encode(&mut self.buf).map_err(|e| e.to_string())?;
        self.buf.extend_from_slice(self.member_records.with_forces(forces));
        self.write_buf(self.channels.members, ns)
    }

    fn log_stage(&mut self, stage: &Stage, t: f64) -> Result<(), Error> {
        let ns = self.clock.stage_stamp(t);
        self.log(self.channels.stage, ns, &msg::StageStart { name: stage.name().into() })
    }

    /// Scene and member forces of one state, and its energy when there is one.
    fn log_state(
        &mut self,
        stage: &Stage,
        step: usize,
        ns: u64,
        positions: &[Vector3<f64>],
        forces: &[f64],
        energy: Option<Energy>,
    ) -> Result<(), Error> {
        self.encode_scene(stage, step, ns, positions, forces);
        self.write_buf(self.channels.scene, ns)?;
        self.log_members(stage, step, ns, forces)?;
        if let Some(e) = energy {
            let total = e.kinetic + e.strain + e.damping - e.external - e.actuation;
            let energy = msg::Energy {
                stage: stage.name().into(),
                step: step as u64,
                kinetic: e.kinetic,
                strain: e.strain,
                damping: e.damping,
                external: e.external,
                actuation: e.actuation,
                total,
            };
            self.log(self.channels.energy, ns, &energy)?;
        }
        Ok(())
    }

    /// `/tsim/scene` into `self.buf`: the `tensegrity` entity's head, the node records
    /// with this step's positions, its lines, then its legend (see [`NodeRecords`] and
    /// [`encode_lines`]).
    fn encode_scene(&mut self, stage: &Stage, step: usize, ns: u64, positions: &[Vector3<f64>], forces: &[f64]) {
        let (head, tail) = self.scene(stage, step, ns, positions, forces);
        self.nodes.set_positions(positions);
        self.lines.clear();
        encode_lines(&mut self.lines, &mut self.buckets, &self.nodes);
        let len = prost_len(&head) + self.nodes.bytes.len() + self.lines.len() + prost_len(&tail);
        self.buf.clear();
        self.buf.push(0x12); // SceneUpdate field 2 (entities), length-delimited
        put_varint(&mut self.buf, len);
        head.encode(&mut self.buf).expect("a Vec grows");
        self.buf.extend_from_slice(&self.nodes.bytes);
        self.buf.extend_from_slice(&self.lines);
        tail.encode(&mut self.buf).expect("a Vec grows");
    }

    /// The scene entity's head (timestamp, frame, id) and its legend; the members' end
    /// nodes sorted into `self.buckets` for [`encode_lines`]. Members are coloured by force
    /// on two scales, each topped by the step's largest force of its sign: tension grey-red to
    /// full red, compression grey-blue to full blue, in [`LEVELS`] shades; slack members (|N| at most [`SLACK_FRACTION`] of the largest,
    /// or a cable in compression) grey. One `LINE_LIST` per (kind, colour) present: half the
    /// size of per-vertex colours.
    fn scene(&mut self, stage: &Stage, step: usize, ns: u64, positions: &[Vector3<f64>], forces: &[f64]) -> (SceneEntity, SceneEntity) {
        let (mut tension, mut compression) = (0.0_f64, 0.0_f64);
        for &f in forces {
            tension = tension.max(f);
            compression = compression.max(-f);
        }
        let eps = SLACK_FRACTION * tension.max(compression);
        let states = 1 + 2 * LEVELS;
        for ((ends, kind), &force) in self.members.iter().zip(forces) {
            let state = if force.abs() <= eps || (*kind == MemberKind::Cable && force < 0.0) {
                0
            } else if force > 0.0 {
                level(force, tension)
            } else {
                LEVELS + level(force, compression)
            };
            let bucket = states * usize::from(*kind == MemberKind::Cable) + state;
            self.buckets[bucket].extend(ends);
        }
        let close = self.nearest.filter(|n| n.clearance < NEAR_RADII * n.radius);
        let at = *self.legend_at.get_or_insert_with(|| legend_position(positions, self.node_size));
        let scale = |max: f64| if max > 0.0 { format!("max {} N", sig3(max)) } else { "none".into() };
        let mut text = format!(
            "{} step {step}\ntension: red, {}\ncompression: blue, {}\nslack: grey; shade = |N| / max in {LEVELS} steps\n{}",
            stage.name(),
            scale(tension),
            scale(compression),
            self.legend_key,
        );
        if let Some(n) = close {
            let [a, b] = n.members.map(|m| self.member_ids[m].as_str());
            text.push_str(&format!("\nclosest struts {a}, {b}: clearance {} m (magenta)", sig3(n.clearance)));
        }
        let legend = TextPrimitive {
            pose: Some(Pose {
                position: Some(foxglove::messages::Vector3 { x: at.x, y: at.y, z: at.z }),
                orientation: Some(Quaternion {
                    w: 1.0,
                    ..Default::default()
                }),
            }),
            billboard: true,
            font_size: LEGEND_FONT,
            scale_invariant: true,
            color: Some(TEXT),
            text,
        };
        let timestamp = Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32);
        let head = SceneEntity {
            timestamp: Some(timestamp),
            frame_id: "world".into(),
            id: "tensegrity".into(),
            ..Default::default()
        };
        // The highlight goes with the legend, after the hand-encoded lines: a repeated field
        // may continue anywhere in the message.
        let tail = SceneEntity {
            lines: close.map(|n| self.highlight(&n, positions)).into_iter().collect(),
            texts: vec![legend],
            ..Default::default()
        };
        (head, tail)
    }

    /// The closest pair's two struts and the link between their closest points, as one
    /// thick magenta `LINE_LIST`.
    fn highlight(&self, n: &Nearest, positions: &[Vector3<f64>]) -> LinePrimitive {
        let point = |p: &Vector3<f64>| Point3 { x: p.x, y: p.y, z: p.z };
        let ends = n.members.iter().flat_map(|&m| self.members[m].0).map(|k| point(&positions[k]));
        LinePrimitive {
            r#type: line_primitive::Type::LineList as i32,
            thickness: 2.0 * STRUT_WIDTH,
            scale_invariant: true,
            points: ends.chain(n.points.iter().map(point)).collect(),
            color: Some(MAGENTA),
            ..Default::default()
        }
    }

    fn record_frame(&mut self, frame: &Frame) -> Result<(), Error> {
        let stage = self.stage.clone().ok_or("MCAP: frame outside a time-stepping stage")?;
        let t = self.clock.frame_time(frame);
        let nearest = frame.clearance.and_then(|c| c.nearest);
        // 1e-9: a time step that divides the interval exactly is not lost to round-off.
        let due = stage.is_static() || self.logged_at.is_none_or(|at| frame.time - at >= self.min_interval * (1.0 - 1e-9));
        self.holding = !due;
        if !due {
            let h = &mut self.held;
            (h.step, h.t, h.energy, h.nearest) = (frame.step, t, frame.energy, nearest);
            h.positions.clear();
            h.positions.extend_from_slice(frame.positions);
            h.forces.clear();
            h.forces.extend_from_slice(frame.forces);
            return Ok(());
        }
        self.logged_at = Some(frame.time);
        let ns = self.clock.step_stamp(t);
        self.nearest = nearest;
        self.log_state(&stage, frame.step, ns, frame.positions, frame.forces, Some(frame.energy))
    }

    /// Logs the stage's last frame if [`Self::record_frame`] held it back.
    fn log_held(&mut self, stage: &Stage) -> Result<(), Error> {
        self.logged_at = None;
        if !std::mem::take(&mut self.holding) {
            return Ok(());
        }
        let h = std::mem::take(&mut self.held);
        let ns = self.clock.step_stamp(h.t);
        self.nearest = h.nearest;
        let logged = self.log_state(stage, h.step, ns, &h.positions, &h.forces, Some(h.energy));
        self.held = h;
        logged
    }
}

fn prost_len(entity: &SceneEntity) -> usize {
    entity.encoded_len().expect("prost messages know their length")
}

/// Node sphere diameter [m]: [`NODE_SIZE`] times the median member length of the model's
/// initial shape (a fraction of its extent without members, 0.05 m for a single point).
fn node_size(model: &Model) -> f64 {
    let xyz: Vec<_> = model.positions();
    let mut lengths: Vec<f64> = model
        .members
        .iter()
        .map(|m| (xyz[m.nodes[1]] - xyz[m.nodes[0]]).norm())
        .filter(|l| *l > 0.0 && l.is_finite())
        .collect();
    lengths.sort_by(f64::total_cmp);
    if let Some(&median) = lengths.get(lengths.len() / 2) {
        return NODE_SIZE * median;
    }
    let (lo, hi) = bounds(&xyz);
    let extent = (hi - lo).norm();
    if extent > 0.0 && extent.is_finite() {
        0.02 * extent
    } else {
        0.05
    }
}

fn bounds(xyz: &[Vector3<f64>]) -> (Vector3<f64>, Vector3<f64>) {
    let lo = xyz.iter().fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
    let hi = xyz.iter().fold(Vector3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p));
    (lo, hi)
}

/// Above the middle of the shape's top, clear of it by a tenth of its extent (at least
/// four node diameters).
fn legend_position(xyz: &[Vector3<f64>], node_size: f64) -> Vector3<f64> {
    if xyz.is_empty() {
        return Vector3::zeros();
    }
    let (lo, hi) = bounds(xyz);
    let clear = (0.1 * (hi - lo).norm()).max(4.0 * node_size);
    Vector3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), hi.z + clear)
}

/// Registers topic `topic` with `T`'s schema and encoding.
fn channel<T: Encode>(writer: &mut mcap::Writer<BufWriter<File>>, topic: &str) -> Result<u16, Error> {
    let schema = T::get_schema().ok_or("message type without a schema")?;
    let schema_id = writer.add_schema(&schema.name, &schema.encoding, &schema.data)?;
    Ok(writer.add_channel(schema_id, topic, &T::get_message_encoding(), &BTreeMap::new())?)
}

/// Places stages and steps on the log timeline (see the module documentation).
#[derive(Default)]
struct Clock {
    /// Log time at which the next stage starts [s].
    next: f64,
    /// Start of the current stage [s].
    origin: f64,
    folding: bool,
    /// Time within the stage of the latest frame, and the increment that led to it [s].
    latest: Option<f64>,
    step: f64,
    last_step_ns: Option<u64>,
    last_stage_ns: Option<u64>,
}

impl Clock {
    fn begin(&mut self, folding: bool) {
        self.origin = self.next;
        self.folding = folding;
        self.latest = None;
        self.step = STATIC_STEP;
    }

    /// Log time of `frame` [s]; also tracks the stage's last step.
    fn frame_time(&mut self, frame: &Frame) -> f64 {
        let t = if self.folding {
            frame.step as f64 * STATIC_STEP
        } else {
            frame.time
        };
        if let Some(prev) = self.latest.filter(|&p| t > p) {
            self.step = t - prev;
        }
        self.latest = Some(t);
        self.origin + t
    }

    fn end(&mut self) {
        self.next = self.origin + self.latest.unwrap_or(0.0) + self.step;
    }

    /// Advances past a static stage of one step.
    fn static_step(&mut self) -> f64 {
        let t = self.next;
        self.next += STATIC_STEP;
        t
    }

    fn step_stamp(&mut self, t: f64) -> u64 {
        let ns = nanos(t).max(self.last_step_ns.map_or(0, |l| l + 1));
        self.last_step_ns = Some(ns);
        ns
    }

    /// Never before the previous step: a stage message opens its stage.
    fn stage_stamp(&mut self, t: f64) -> u64 {
        let after = |last: Option<u64>| last.map_or(0, |l| l + 1);
        let ns = nanos(t).max(after(self.last_stage_ns)).max(after(self.last_step_ns));
        self.last_stage_ns = Some(ns);
        ns
    }
}

fn nanos(t: f64) -> u64 {
    (t.max(0.0) * 1e9).round() as u64
}

impl Recorder for McapRecorder {
    fn model(&mut self, record: &ModelRecord) -> RecordResult {
        self.members = record.model.members.iter().map(|m| (m.nodes, m.kind)).collect();
        self.member_ids = record.model.members.iter().map(|m| m.id.clone()).collect();
        self.member_records = MemberRecords::new(record.model.members.iter().map(|m| m.id.as_str()));
        let supports: Vec<usize> = record
            .model
            .nodes
            .iter()
            .map(|n| n.support.iter().filter(|&&s| s).count())
            .collect();
        self.node_size = node_size(record.model);
        self.nodes = NodeRecords::new(&supports, self.node_size);
        let fixed = supports.iter().filter(|&&s| s == 3).count();
        let partly = supports.iter().filter(|&&s| s > 0 && s < 3).count();
        self.legend_key = match (fixed, partly) {
            (0, 0) => "nodes: gold".into(),
            (_, 0) => "nodes: gold; supports: green cubes".into(),
            (0, _) => "nodes: gold; supports: purple cubes (some directions)".into(),
            _ => "nodes: gold; supports: green cubes (purple: some directions)".into(),
        };
        Ok(())
    }

    fn formfinding(&mut self, record: &FormFindRecord) -> RecordResult {
        let t = self.clock.static_step();
        self.log_stage(record.stage, t)?;
        let ns = self.clock.step_stamp(t);
        self.nearest = record.clearance.and_then(|c| c.nearest);
        self.log_state(record.stage, 0, ns, record.positions, record.forces, None)
    }

    fn eigen(&mut self, record: &crate::record::EigenRecord) -> RecordResult {
        let t = self.clock.static_step();
        self.log_stage(record.stage, t)
    }

    fn begin_stage(&mut self, stage: &Stage, _constraints: &crate::record::Constraints) -> RecordResult {
        self.clock.begin(stage.is_static());
        self.stage = Some(stage.clone());
        self.log_stage(stage, self.clock.origin)
    }

    fn frame(&mut self, frame: &Frame) -> RecordResult {
        self.record_frame(frame)
    }

    fn end_stage(&mut self, stage: &Stage) -> RecordResult {
        self.log_held(stage)?;
        self.clock.end();
        self.stage = None;
        Ok(())
    }

    fn finish(&mut self, outcome: &Outcome) -> RecordResult {
        if let Some(stage) = self.stage.clone() {
            self.end_stage(&stage)?;
        }
        let mut writer = self.writer.take().ok_or("MCAP recorder already finished")?;
        let metadata = BTreeMap::from([("status".to_string(), outcome.to_string())]);
        writer.write_metadata(&mcap::records::Metadata {
            name: "status".into(),
            metadata,
        })?;
        writer.finish()?;
        Ok(())
    }
}

impl Drop for McapRecorder {
    /// A recorder dropped without `finish` (an unwinding panic) still closes a readable file,
    /// saying why it ended early.
    fn drop(&mut self) {
        if self.writer.is_some() {
            let _ = self.finish(&Outcome::Failed("recorder dropped before finish".into()));
        }
    }
}

#[cfg(test)]
mod tests {
    /// WCAG 2 relative luminance of an sRGB colour.
    fn luminance(c: Color) -> f64 {
        let lin = |v: f64| if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) };
        0.2126 * lin(c.r) + 0.7152 * lin(c.g) + 0.0722 * lin(c.b)
    }

    /// Contrast against the darker of black and white backgrounds, whichever is worse.
    fn worst_contrast(c: Color) -> f64 {
        let l = luminance(c);
        f64::min((l + 0.05) / 0.05, 1.05 / (l + 0.05))
    }

    /// Foxglove's 3-D panel is near black on the dark theme and near white on the light
    /// one: the legend must read on both (WCAG 4.5:1 for text) and every member's colour
    /// must stand out on both (3:1, WCAG's non-text contrast).
    #[test]
    fn legend_and_members_read_on_dark_and_light_themes() {
        assert!(worst_contrast(TEXT) >= 4.5, "legend: {}", worst_contrast(TEXT));
        for state in 0..=2 * LEVELS {
            let c = worst_contrast(state_colour(state));
            assert!(c >= 3.0, "line state {state}: {c}");
        }
    }

    use super::*;
    use crate::model::generate::TowerSpec;
    use crate::output::h5::tests::{drive, temp_path};

    /// The patched records give the bytes the derive encodes, ids of any length included.
    #[test]
    fn member_records_encode_as_the_message_does() {
        let ids: Vec<String> = ["a", "strut0_0", &"c".repeat(200)].iter().map(|s| s.to_string()).collect();
        let mut records = MemberRecords::new(ids.iter().map(String::as_str));
        for forces in [[1.5, -2.25e3, 0.0], [f64::MAX, -0.0, 1e-300]] {
            let mut ours = Vec::new();
            let head = msg::MemberForces {
                stage: "deployment".into(),
                step: 300,
                members: Vec::new(),
            };
            head.encode(&mut ours).unwrap();
            ours.extend_from_slice(records.with_forces(&forces));
            let full = msg::MemberForces {
                members: ids
                    .iter()
                    .zip(forces)
                    .map(|(id, force)| msg::MemberForce { id: id.clone(), force })
                    .collect(),
                ..head
            };
            let mut derived = Vec::new();
            full.encode(&mut derived).unwrap();
            assert_eq!(ours, derived);
        }
    }

    #[test]
    fn logs_every_recorded_step_on_one_increasing_timeline() {
        let model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let (_dir, path) = temp_path("replay.mcap");
        let mut rec = McapRecorder::create(&path, "case-7", 0.0).unwrap();
        drive(&mut rec, &model, 10, 3).unwrap();
        rec.finish(&Outcome::Complete).unwrap();

        let bytes = std::fs::read(&path).unwrap();
        let mut times: BTreeMap<String, Vec<u64>> = BTreeMap::new();
        let mut schemas = BTreeMap::new();
        for message in mcap::MessageStream::new(&bytes).unwrap() {
            let message = message.unwrap();
            let topic = message.channel.topic.clone();
            schemas.insert(topic.clone(), message.channel.schema.as_ref().unwrap().name.clone());
            times.entry(topic).or_default().push(message.log_time);
        }
        assert_eq!(schemas["/tsim/scene"], "foxglove.SceneUpdate");
        assert_eq!(schemas["/tsim/energy"], "energy.Energy");
        // Steps 0, 3, 6, 9, 10 of three stages; form-finding adds a scene and members.
        assert_eq!(times["/tsim/energy"].len(), 15);
        assert_eq!(times["/tsim/scene"].len(), 16);
        assert_eq!(times["/tsim/members"].len(), 16);
        assert_eq!(times["/tsim/stage"].len(), 5);
        for t in times.values() {
            assert!(t.windows(2).all(|w| w[0] < w[1]), "{t:?}");
        }
        // Form-finding at 0, eigen at 0.1 s, free vibration from 0.2 s to 0.3 s (steps of
        // 0.01 s), folding from 0.31 s in steps of 0.1 s to 1.31 s, deployment from 1.41 s.
        let ms = |t: &u64| (*t as f64 / 1e6).round() as u64;
        assert_eq!(times["/tsim/stage"].iter().map(ms).collect::<Vec<_>>(), [0, 100, 200, 310, 1410]);
        assert_eq!(
            times["/tsim/energy"][..6].iter().map(ms).collect::<Vec<_>>(),
            [200, 230, 260, 290, 300, 310]
        );

        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        assert!(summary.chunk_indexes.iter().all(|c| c.compression == "zstd"));
    }

    /// `replay_rate` thins the time-stepping stages' frames (not folding's), keeps each
    /// stage's first and last frame, and leaves the timeline as it was.
    #[test]
    fn replay_rate_thins_frames_but_keeps_each_stages_ends() {
        let model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let (_dir, path) = temp_path("thinned.mcap");
        // 20 Hz: at least 50 ms between logged frames; `drive` gives steps 0, 3, 6, 9, 10 at
        // 10 ms a step, so steps 0, 6 and 10 (the last, held back and logged at the end).
        let mut rec = McapRecorder::create(&path, "case-7", 20.0).unwrap();
        drive(&mut rec, &model, 10, 3).unwrap();
        rec.finish(&Outcome::Complete).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut times: BTreeMap<String, Vec<u64>> = BTreeMap::new();
        for message in mcap::MessageStream::new(&bytes).unwrap() {
            let message = message.unwrap();
            let ms = (message.log_time as f64 / 1e6).round() as u64;
            times.entry(message.channel.topic.clone()).or_default().push(ms);
        }
        // Free vibration from 0.2 s: steps 0, 6, 10; folding from 0.31 s, 0.1 s a step,
        // every step; deployment from 1.41 s: steps 0, 6, 10.
        let thinned = [200, 260, 300, 310, 610, 910, 1210, 1310, 1410, 1470, 1510];
        assert_eq!(times["/tsim/energy"], thinned);
        assert_eq!(times["/tsim/scene"][1..], thinned);
        assert_eq!(times["/tsim/members"][1..], thinned);
        assert_eq!(times["/tsim/stage"], [0, 100, 200, 310, 1410]);
    }

    fn scene_recorder(model: &Model, name: &str) -> McapRecorder {
        let (_dir, path) = temp_path(name);
        let mut rec = McapRecorder::create(&path, "c", 0.0).unwrap();
        let members = model.members.len();
        rec.model(&ModelRecord {
            model,
            rest_lengths: &vec![1.0; members],
            masses: &vec![1.0; model.node_count()],
            mass_reading: "physical",
            stages: &[],
        })
        .unwrap();
        rec
    }

    fn decoded_scene(rec: &mut McapRecorder, positions: &[Vector3<f64>], forces: &[f64]) -> SceneEntity {
        rec.encode_scene(
            &Stage::new(crate::record::StageKind::Transient, "deployment"),
            7,
            1_500_000_000,
            positions,
            forces,
        );
        let mut update = <SceneUpdate as foxglove::Decode>::decode(rec.buf.as_slice()).unwrap();
        assert_eq!(update.entities.len(), 1);
        update.entities.remove(0)
    }

    #[test]
    fn colours_members_by_force() {
        let model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let mut rec = scene_recorder(&model, "colours.mcap");
        // Struts, then side cables (the second below the slack threshold), then rings.
        let forces = [-5.0, -1.0, 0.0, 2.0, 1e-9, -1.0, 3.0, 3.0, 3.0, 0.5, 8.0, 8.0];
        let entity = decoded_scene(&mut rec, &model.positions(), &forces);
        let summary: Vec<_> = entity
            .lines
            .iter()
            .map(|l| (l.thickness, l.color.unwrap(), l.points.len()))
            .collect();
        let (s, c) = (STRUT_WIDTH, CABLE_WIDTH);
        // Compression scale topped by 5 N: −1 N is shade 1, −5 N shade 4; tension by 8 N:
        // 0.5 N shade 1, 2 N shade 1, 3 N shade 2, 8 N shade 4.
        let shade = |n| state_colour(n);
        assert_eq!(
            summary,
            [
                (s, GREY, 2),
                (s, shade(LEVELS + 1), 2),
                (s, shade(2 * LEVELS), 2),
                (c, GREY, 4),
                (c, shade(1), 4),
                (c, shade(2), 6),
                (c, shade(4), 4),
            ]
        );
        assert_eq!(shade(LEVELS), RED);
        assert_eq!(shade(2 * LEVELS), BLUE);
        let legend = &entity.texts[0].text;
        assert!(legend.contains("tension: red, max 8.00 N"), "{legend}");
        assert!(legend.contains("compression: blue, max 5.00 N"), "{legend}");
        assert!(legend.contains("deployment step 7"), "{legend}");
        rec.finish(&Outcome::Complete).unwrap();
    }

    /// The closest strut pair is drawn in magenta, with the link of its closest points, and
    /// named in the legend when its clearance is below 2 × the larger radius; not above.
    #[test]
    fn highlights_the_closest_pair_when_near() {
        let model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let mut rec = scene_recorder(&model, "near.mcap");
        let x = model.positions();
        let forces = vec![1.0; model.members.len()];
        let near = |clearance| Nearest {
            clearance,
            members: [0, 2],
            points: [x[0], x[1]],
            radius: 0.05,
        };
        rec.nearest = Some(near(0.099));
        let entity = decoded_scene(&mut rec, &x, &forces);
        let last = entity.lines.last().unwrap();
        assert_eq!(
            (last.color.unwrap(), last.thickness, last.points.len()),
            (MAGENTA, 2.0 * STRUT_WIDTH, 6)
        );
        let [a, b] = [0, 2].map(|m| model.members[m].id.as_str());
        let legend = &entity.texts[0].text;
        assert!(legend.contains(&format!("closest struts {a}, {b}: clearance 0.0990 m")), "{legend}");
        rec.nearest = Some(near(0.101));
        let entity = decoded_scene(&mut rec, &x, &forces);
        assert!(entity.lines.iter().all(|l| l.color.unwrap() != MAGENTA));
        assert!(!entity.texts[0].text.contains("closest"));
        rec.finish(&Outcome::Complete).unwrap();
    }

    /// Spheres at free nodes, cubes at supported ones, at this step's positions; the
    /// bytes are prost's for the whole update when no coordinate is zero.
    #[test]
    fn marks_nodes_and_supports_with_the_bytes_prost_encodes() {
        let mut model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        model.nodes[1].support = [false, false, true];
        let supports: Vec<_> = model.nodes.iter().map(|n| n.support.iter().filter(|&&s| s).count()).collect();
        assert!(supports.contains(&3) && supports.contains(&0));
        let mut rec = scene_recorder(&model, "nodes.mcap");
        let shifted: Vec<_> = model.positions().iter().map(|p| p + Vector3::new(0.25, -0.5, 1.5)).collect();
        let forces = [-5.0, -5.0, -5.0, 2.0, 2.0, 2.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0];
        let entity = decoded_scene(&mut rec, &shifted, &forces);
        let d = rec.node_size;
        assert!(d > 0.0);
        let at = |pose: &Option<Pose>| {
            let p = pose.as_ref().unwrap().position.as_ref().unwrap();
            Vector3::new(p.x, p.y, p.z)
        };
        let free: Vec<_> = (0..6).filter(|&n| supports[n] == 0).collect();
        let held: Vec<_> = (0..6).filter(|&n| supports[n] > 0).collect();
        assert_eq!(entity.spheres.len(), free.len());
        assert_eq!(entity.cubes.len(), held.len());
        for (sphere, &n) in entity.spheres.iter().zip(&free) {
            assert_eq!(at(&sphere.pose), shifted[n]);
            assert_eq!(sphere.size.as_ref().unwrap().x, d);
            assert_eq!(sphere.color, Some(GOLD));
        }
        for (cube, &n) in entity.cubes.iter().zip(&held) {
            assert_eq!(at(&cube.pose), shifted[n]);
            assert_eq!(cube.size.as_ref().unwrap().z, SUPPORT_SIZE * d);
            assert_eq!(cube.color, Some(if supports[n] == 3 { GREEN } else { PURPLE }));
        }
        assert!(entity.texts[0].text.contains("purple: some directions"));

        // Prost's bytes for the decoded update equal ours.
        let ours = rec.buf.clone();
        let mut theirs = Vec::new();
        SceneUpdate {
            entities: vec![entity],
            ..Default::default()
        }
        .encode(&mut theirs)
        .unwrap();
        assert_eq!(ours, theirs);

        // A zero coordinate is written, and reads back as zero.
        let mut zeros = shifted.clone();
        zeros[0] = Vector3::zeros();
        let entity = decoded_scene(&mut rec, &zeros, &forces);
        let first = if supports[0] > 0 {
            &entity.cubes[0].pose
        } else {
            &entity.spheres[0].pose
        };
        assert_eq!(at(first), Vector3::zeros());
        rec.finish(&Outcome::Complete).unwrap();
    }

    #[test]
    fn formats_three_significant_digits() {
        let got: Vec<_> = [0.0, 1234.4, 8.0, 0.01234, 123_456.0, -2.5e-4].map(sig3).into();
        assert_eq!(got, ["0", "1234", "8.00", "0.0123", "1.23e5", "-2.50e-4"]);
    }
}
