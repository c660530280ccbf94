//! `replay.mcap`: every stage of a case on one timeline for Foxglove (issue 4 is the
//! contract; topic names and Foxglove schema names must not change).
//!
//! Topics (protobuf, zstd-compressed chunks):
//! - `/tsim/scene` (`foxglove.SceneUpdate`): struts and cables as `LINE_LIST` primitives in
//!   frame `world`, each member coloured by state: compression brown, tension red, slack grey
//!   (the paper's colours).
//! - `/tsim/energy` (`energy.Energy`): kinetic, strain, damping, external and total energy.
//! - `/tsim/members` (`memberforces.MemberForces`): every member's id and force; in a Plot
//!   panel, `/tsim/members.members[:]{id=="strut0_0"}.force`.
//! - `/tsim/stage` (`stagestart.StageStart`): one message at the start of each stage.
//!
//! Scene, energy and members are logged together at every recorded step of a time-stepping
//! stage; form-finding logs one scene and one members message (its equilibrium; it has no
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

use crate::model::MemberKind;
use crate::record::{Energy, FormFindRecord, Frame, ModelRecord, Outcome, RecordResult, Recorder, Stage};
use foxglove::messages::{line_primitive, Color, LinePrimitive, Point3, SceneEntity, SceneUpdate, Timestamp};
use foxglove::Encode;
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

type Error = Box<dyn std::error::Error + Send + Sync>;

/// Synthetic duration of one step of a static stage on the log timeline [s].
pub const STATIC_STEP: f64 = 0.1;
/// Line widths [px], independent of zoom so that any model size reads well.
const STRUT_WIDTH: f64 = 6.0;
const CABLE_WIDTH: f64 = 2.0;
/// A member whose |force| is below this fraction of the step's largest |force| is slack.
const SLACK_FRACTION: f64 = 1e-6;
const BROWN: Color = Color {
    r: 0.55,
    g: 0.27,
    b: 0.07,
    a: 1.0,
};
const RED: Color = Color {
    r: 0.85,
    g: 0.10,
    b: 0.10,
    a: 1.0,
};
const GREY: Color = Color {
    r: 0.60,
    g: 0.60,
    b: 0.60,
    a: 1.0,
};

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
        /// kinetic + strain + damping − external: the energy balance, constant while the
        /// integration conserves energy.
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
    /// The `/tsim/members` message's member records, encoded once.
    member_records: MemberRecords,
    /// Point buffers of the scene's lines, one per (kind, state), reused between steps.
    points: [Vec<Point3>; 6],
    stage: Option<Stage>,
    buf: Vec<u8>,
}

struct Channels {
    scene: u16,
    energy: u16,
    members: u16,
    stage: u16,
}

impl McapRecorder {
    /// Creates (truncates) `path`. Every frame given is logged: the output stride is applied
    /// by the stages.
    pub fn create(path: &Path, case_id: &str) -> Result<Self, Error> {
        // zstd level 1: level 3 (the default) spent 5 % of the paper case in compression for
        // files 2 % smaller. Single-threaded: the recorder has a thread of its own (see
        // `Background`), and zstd's own workers would compete with the solver.
        let options = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1)
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
            member_records: MemberRecords::default(),
            points: Default::default(),
            stage: None,
            buf: Vec::new(),
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
    fn log_members(&mut self, stage: Stage, step: usize, ns: u64, forces: &[f64]) -> Result<(), Error> {
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

    fn log_stage(&mut self, stage: Stage, t: f64) -> Result<(), Error> {
        let ns = self.clock.stage_stamp(t);
        self.log(self.channels.stage, ns, &msg::StageStart { name: stage.name().into() })
    }

    /// Scene and member forces of one state, and its energy when there is one.
    fn log_state(
        &mut self,
        stage: Stage,
        step: usize,
        ns: u64,
        positions: &[Vector3<f64>],
        forces: &[f64],
        energy: Option<Energy>,
    ) -> Result<(), Error> {
        let scene = self.scene(ns, positions, forces);
        self.log(self.channels.scene, ns, &scene)?;
        self.reclaim(scene);
        self.log_members(stage, step, ns, forces)?;
        if let Some(e) = energy {
            let total = e.kinetic + e.strain + e.damping - e.external;
            let energy = msg::Energy {
                stage: stage.name().into(),
                step: step as u64,
                kinetic: e.kinetic,
                strain: e.strain,
                damping: e.damping,
                external: e.external,
                total,
            };
            self.log(self.channels.energy, ns, &energy)?;
        }
        Ok(())
    }

    /// One `LINE_LIST` per (kind, state) present, each of one colour: half the size of
    /// per-vertex colours. The point buffers come from `self.points`; give the scene back to
    /// [`McapRecorder::reclaim`] once encoded.
    fn scene(&mut self, ns: u64, positions: &[Vector3<f64>], forces: &[f64]) -> SceneUpdate {
        let eps = SLACK_FRACTION * forces.iter().fold(0.0_f64, |m, f| m.max(f.abs()));
        // Bucket = 3 × kind (strut 0, cable 1) + state (brown 0, red 1, grey 2).
        for ((ends, kind), &force) in self.members.iter().zip(forces) {
            let state = if force.abs() <= eps || (*kind == MemberKind::Cable && force < 0.0) {
                2
            } else if force < 0.0 {
                0
            } else {
                1
            };
            let bucket = 3 * usize::from(*kind == MemberKind::Cable) + state;
            self.points[bucket].extend(ends.map(|n| Point3 {
                x: positions[n].x,
                y: positions[n].y,
                z: positions[n].z,
            }));
        }
        let mut lines = Vec::new();
        for (bucket, points) in self.points.iter_mut().enumerate() {
            if !points.is_empty() {
                lines.push(LinePrimitive {
                    r#type: line_primitive::Type::LineList as i32,
                    thickness: if bucket < 3 { STRUT_WIDTH } else { CABLE_WIDTH },
                    scale_invariant: true,
                    points: std::mem::take(points),
                    color: Some([BROWN, RED, GREY][bucket % 3]),
                    ..Default::default()
                });
            }
        }
        let timestamp = Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32);
        let entity = SceneEntity {
            timestamp: Some(timestamp),
            frame_id: "world".into(),
            id: "tensegrity".into(),
            lines,
            ..Default::default()
        };
        SceneUpdate {
            entities: vec![entity],
            ..Default::default()
        }
    }

    /// Returns the point buffers of a scene made by [`McapRecorder::scene`] for reuse.
    fn reclaim(&mut self, scene: SceneUpdate) {
        let lines = scene.entities.into_iter().flat_map(|e| e.lines);
        for (slot, mut line) in self.points.iter_mut().filter(|p| p.is_empty()).zip(lines) {
            line.points.clear();
            *slot = line.points;
        }
    }

    fn record_frame(&mut self, frame: &Frame) -> Result<(), Error> {
        let stage = self.stage.ok_or("MCAP: frame outside a time-stepping stage")?;
        let t = self.clock.frame_time(frame);
        let ns = self.clock.step_stamp(t);
        self.log_state(stage, frame.step, ns, frame.positions, frame.forces, Some(frame.energy))
    }
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
        self.member_records = MemberRecords::new(record.model.members.iter().map(|m| m.id.as_str()));
        Ok(())
    }

    fn formfinding(&mut self, record: &FormFindRecord) -> RecordResult {
        let t = self.clock.static_step();
        self.log_stage(record.stage, t)?;
        let ns = self.clock.step_stamp(t);
        self.log_state(record.stage, 0, ns, record.positions, record.forces, None)
    }

    fn eigen(&mut self, _record: &crate::record::EigenRecord) -> RecordResult {
        let t = self.clock.static_step();
        self.log_stage(Stage::Eigen, t)
    }

    fn begin_stage(&mut self, stage: Stage, _constraints: &crate::record::Constraints) -> RecordResult {
        self.clock.begin(stage.is_static());
        self.stage = Some(stage);
        self.log_stage(stage, self.clock.origin)
    }

    fn frame(&mut self, frame: &Frame) -> RecordResult {
        self.record_frame(frame)
    }

    fn end_stage(&mut self, _stage: Stage) -> RecordResult {
        self.clock.end();
        self.stage = None;
        Ok(())
    }

    fn finish(&mut self, outcome: &Outcome) -> RecordResult {
        if let Some(stage) = self.stage {
            self.end_stage(stage)?;
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
        let path = temp_path("replay.mcap");
        let mut rec = McapRecorder::create(&path, "case-7").unwrap();
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

    #[test]
    fn colours_members_by_state() {
        let model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let path = temp_path("colours.mcap");
        let mut rec = McapRecorder::create(&path, "c").unwrap();
        rec.model(&ModelRecord {
            model: &model,
            rest_lengths: &[1.0; 12],
            masses: &[1.0; 6],
            mass_reading: "physical",
            constraints: &[],
            path_modes: 0,
        })
        .unwrap();
        // Struts, then side cables (the second below the slack threshold), then rings.
        let forces = [-5.0, -5.0, 0.0, 2.0, 1e-9, -1.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0];
        let scene = rec.scene(0, &model.positions(), &forces);
        let summary: Vec<_> = scene.entities[0]
            .lines
            .iter()
            .map(|l| (l.thickness, l.color.unwrap(), l.points.len()))
            .collect();
        let (s, c) = (STRUT_WIDTH, CABLE_WIDTH);
        assert_eq!(summary, [(s, BROWN, 4), (s, GREY, 2), (c, RED, 14), (c, GREY, 4)]);
        rec.finish(&Outcome::Complete).unwrap();
    }
}
