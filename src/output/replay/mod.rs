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
//!   them with their clearance. Contacts (`contact`) are orange arrows from each contact
//!   point along its normal, lengths in proportion to the forces, the legend counting them
//!   with the largest force.
//! - `/tsim/energy` (`energy.Energy`): kinetic, strain, damping, external and total energy.
//! - `/tsim/members` (`memberforces.MemberForces`): every member's id and force; in a Plot
//!   panel, `/tsim/members.members[:]{id=="strut0_0"}.force`.
//! - `/tsim/stage` (`stagestart.StageStart`): one message at the start of each stage.
//! - `/tsim/clusters` (`cables.Cables`), a model with clustered cables only: each cable's
//!   tension and its slide over each pulley (`cables.rs`), with the scene in every stage
//!   that records rest lengths.
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

mod cables;
mod clock;
mod encode;
mod scene;
#[cfg(test)]
mod tests;

use crate::model::MemberKind;
use crate::record::{Energy, FormFindRecord, Frame, ModelRecord, Nearest, Outcome, RecordResult, Recorder, Stage};
use cables::CableReplay;
use clock::Clock;
use encode::{encode_lines, msg, prost_len, put_varint, MemberRecords, NodeRecords};
use foxglove::messages::{line_primitive, LinePrimitive, Point3, Pose, Quaternion, SceneEntity, SceneUpdate, TextPrimitive, Timestamp};
use foxglove::Encode;
use nalgebra::Vector3;
use scene::{
    contact_arrows, legend_position, level, node_size, sig3, ContactArrow, LEGEND_FONT, LEVELS, MAGENTA, SLACK_FRACTION, STRUT_WIDTH, TEXT,
};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

type Error = Box<dyn std::error::Error + Send + Sync>;

/// zstd level of the MCAP chunks (see [`McapRecorder::create`]).
const ZSTD_LEVEL: i32 = -3;
/// Synthetic duration of one step of a static stage on the log timeline [s].
pub const STATIC_STEP: f64 = 0.1;
/// The closest strut pair is highlighted when its clearance is below this many times the
/// larger of the two radii: about to touch, on the scale of the struts themselves.
pub const NEAR_RADII: f64 = 2.0;

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
    /// The contacts of the state being logged (none without contact).
    contacts: Vec<ContactArrow>,
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
    /// The clustered cables' topic (none without).
    cables: Option<CableReplay>,
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
    contacts: Vec<ContactArrow>,
    rest: Option<Vec<f64>>,
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
        // zstd level −3, a "fast" level: less writer CPU for a somewhat larger file than the
        // default levels (the levels and lz4 measured: bench/outputs.md). mcap takes the
        // level as a u32 and hands it to zstd as an i32, so −3 goes through as its two's
        // complement. Single-threaded: the recorder has a thread of its own (see
        // `Background`), and zstd's own workers would compete with the solver.
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
            contacts: Vec::new(),
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
            cables: None,
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

    /// `/tsim/clusters` at a state with rest lengths `rest` (none: no message, as for a
    /// stage that does not record them, or a model without clustered cables).
    fn log_cables(&mut self, stage: &Stage, step: usize, ns: u64, forces: &[f64], rest: Option<&[f64]>) -> Result<(), Error> {
        let (Some(cables), Some(rest)) = (&mut self.cables, rest) else {
            return Ok(());
        };
        let (channel, message) = (cables.channel, cables.message(stage, step, forces, rest));
        self.log(channel, ns, &message)
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
            let total = e.kinetic + e.strain + e.contact + e.damping - e.external - e.actuation;
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
    /// or a cable in compression) grey. One `LINE_LIST` per (kind, colour) present, not a
    /// colour per vertex (the sizes: bench/outputs.md).
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
        if let Some(max) = self.contacts.iter().map(|c| c.force).reduce(f64::max) {
            text.push_str(&format!("\ncontacts: {}, orange arrows, max {} N", self.contacts.len(), sig3(max)));
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
            arrows: contact_arrows(&self.contacts, self.node_size),
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
        let contacts = frame.contacts.iter().map(|c| ContactArrow {
            point: c.point,
            normal: c.normal,
            force: c.force,
        });
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
            h.contacts.clear();
            h.contacts.extend(contacts);
            h.rest = frame.rest_lengths.map(<[f64]>::to_vec);
            return Ok(());
        }
        self.logged_at = Some(frame.time);
        let ns = self.clock.step_stamp(t);
        self.nearest = nearest;
        self.contacts.clear();
        self.contacts.extend(contacts);
        self.log_state(&stage, frame.step, ns, frame.positions, frame.forces, Some(frame.energy))?;
        self.log_cables(&stage, frame.step, ns, frame.forces, frame.rest_lengths)
    }

    /// Logs the stage's last frame if [`Self::record_frame`] held it back.
    fn log_held(&mut self, stage: &Stage) -> Result<(), Error> {
        self.logged_at = None;
        if !std::mem::take(&mut self.holding) {
            return Ok(());
        }
        let mut h = std::mem::take(&mut self.held);
        let ns = self.clock.step_stamp(h.t);
        self.nearest = h.nearest;
        std::mem::swap(&mut self.contacts, &mut h.contacts);
        let logged = self.log_state(stage, h.step, ns, &h.positions, &h.forces, Some(h.energy));
        let logged = logged.and_then(|()| self.log_cables(stage, h.step, ns, &h.forces, h.rest.as_deref()));
        self.held = h;
        logged
    }
}

/// Registers topic `topic` with `T`'s schema and encoding.
fn channel<T: Encode>(writer: &mut mcap::Writer<BufWriter<File>>, topic: &str) -> Result<u16, Error> {
    let schema = T::get_schema().ok_or("message type without a schema")?;
    let schema_id = writer.add_schema(&schema.name, &schema.encoding, &schema.data)?;
    Ok(writer.add_channel(schema_id, topic, &T::get_message_encoding(), &BTreeMap::new())?)
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
        if !record.model.clusters.is_empty() {
            let writer = self.writer.as_mut().ok_or("MCAP recorder already finished")?;
            let topic = channel::<msg::Cables>(writer, "/tsim/clusters")?;
            self.cables = Some(CableReplay::new(record, topic));
        }
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
        self.contacts.clear();
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
