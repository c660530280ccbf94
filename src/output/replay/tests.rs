use super::encode::{msg, MemberRecords};
use super::scene::{
    sig3, state_colour, BLUE, CABLE_WIDTH, GOLD, GREEN, GREY, LEVELS, MAGENTA, ORANGE, PURPLE, RED, STRUT_WIDTH, SUPPORT_SIZE, TEXT,
};
use super::*;
use crate::model::generate::TowerSpec;
use crate::model::Model;
use crate::output::h5::tests::{drive, temp_path};
use foxglove::messages::Color;

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

/// Contacts are orange arrows from their points along their normals, the largest force's
/// the longest (4 node diameters), the others in proportion, and the legend counts them.
#[test]
fn draws_contact_forces_as_arrows_along_their_normals() {
    let model = TowerSpec {
        struts: 3,
        stages: 1,
        ..TowerSpec::paper()
    }
    .build();
    let mut rec = scene_recorder(&model, "contacts.mcap");
    let x = model.positions();
    let forces = vec![1.0; model.members.len()];
    let normal = Vector3::new(1.0, 2.0, -2.0) / 3.0;
    rec.contacts = vec![
        ContactArrow {
            point: x[0],
            normal,
            force: 300.0,
        },
        ContactArrow {
            point: x[1],
            normal: -Vector3::x(),
            force: 100.0,
        },
    ];
    let entity = decoded_scene(&mut rec, &x, &forces);
    assert_eq!(entity.arrows.len(), 2);
    let length = |a: &foxglove::messages::ArrowPrimitive| a.shaft_length + a.head_length;
    assert!((length(&entity.arrows[0]) - 4.0 * rec.node_size).abs() < 1e-12);
    assert!((length(&entity.arrows[0]) / length(&entity.arrows[1]) - 3.0).abs() < 1e-12);
    // The pose's rotation takes +x to the normal: q (1, 0, 0) q*.
    for (arrow, n) in entity.arrows.iter().zip([normal, -Vector3::x()]) {
        let q = arrow.pose.unwrap().orientation.unwrap();
        let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
        assert!((q * Vector3::x() - n).norm() < 1e-12, "{n:?}");
        assert_eq!(arrow.color.unwrap(), ORANGE);
    }
    assert!(
        entity.texts[0].text.contains("contacts: 2, orange arrows, max 300 N"),
        "{}",
        entity.texts[0].text
    );
    rec.contacts.clear();
    assert!(decoded_scene(&mut rec, &x, &forces).arrows.is_empty());
    rec.finish(&Outcome::Complete).unwrap();
}
