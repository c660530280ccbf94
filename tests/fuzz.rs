//! Property tests of the config loader and the model builder (a fuzz target, run with
//! proptest on stable Rust): configs generated from strategies — towers with any strut
//! and stage counts and extreme lengths, explicit node and member lists with duplicate
//! ids, unknown nodes, coincident or far-flung coordinates, and around them every stage
//! section with edge values — go through the path `tsim check` takes (parse, sweep
//! expansion, validation, model building, the work estimates; with and without
//! `--allow-large`). None may panic, an accepted config's estimates are finite, and every
//! rejection says where (a `file:N:` line, a parse error's `file:N:M:`), as in
//! tests/mutations.rs, which mutates the shipped configs' text instead.
//!
//! Bounded: [`CASES`] generated configs per property (a second or two in release;
//! `TSIM_FUZZ_CASES=N` runs more), from a fixed seed, so
//! that CI runs the same configs every time and a failure there reproduces (set
//! `PROPTEST_RNG_SEED` to explore others). A failing config is shrunk and its seed
//! persisted in `tests/proptest-regressions/<property>.txt`, to be committed: the
//! corpus, replayed first on every run.

use proptest::prelude::*;
use proptest::test_runner::{Config, FileFailurePersistence, RngSeed, TestCaseError, TestRunner};
use std::cell::Cell;
use tsim::config::ConfigError;
use tsim::run::expand;

/// Generated configs per property. 1024 take 0.9–1.6 s per property in release on this
/// project's 2-core machine under load (the two properties run in parallel: 1.4–1.7 s of
/// wall time), small beside the pipeline tests in CI, and still get some 90 towers and
/// 250 node lists through validation each run, so every check and the estimates are
/// reached; searching wider is a job for `TSIM_FUZZ_CASES` and other seeds (3 seeds ×
/// 10 000 configs per property found nothing when this test was written).
const CASES: u32 = 1024;

/// A float as YAML text that reads back as the same f64 (a dot and 17 digits).
fn float(v: f64) -> String {
    format!("{v:.16e}")
}

/// Weight of the ordinary branch of every choice below; the edge branches weigh `e`,
/// which is drawn per config: 1 (a config with an odd value here and there, which often
/// gets through validation) or 10 (one with many).
const USUAL: u32 = 40;

/// Finite values from ordinary to extreme: zero of both signs, the smallest subnormal,
/// the largest finite, negatives.
fn extreme(e: u32) -> impl Strategy<Value = f64> {
    prop_oneof![
        USUAL => -10.0..10.0_f64,
        e => (-3i32..=3).prop_map(f64::from),
        e => prop::sample::select(vec![
            0.0, -0.0, 5e-324, 1e-300, f64::MIN_POSITIVE, 1e-12, 1e15, 1e300, 1e308, -1e308, f64::MAX, -f64::MAX,
        ]),
    ]
}

/// A value in `usual`, or any extreme one.
fn value(usual: std::ops::Range<f64>, e: u32) -> impl Strategy<Value = String> {
    prop_oneof![USUAL => usual.prop_map(float), e => extreme(e).prop_map(float)]
}

/// A length, modulus or factor: positive, or any extreme value.
fn length(e: u32) -> impl Strategy<Value = String> {
    value(0.01..20.0, e)
}

/// A count as YAML text: small, zero, large, past every limit, or not a count at all.
fn count(e: u32) -> impl Strategy<Value = String> {
    prop_oneof![
        USUAL => (1usize..=12).prop_map(|n| n.to_string()),
        e => prop_oneof![Just(0), 13usize..=1000].prop_map(|n| n.to_string()),
        e => prop::sample::select(vec![
            "1000000", "4294967296", "18446744073709551615", "18446744073709551616", "-1", "3.5", "\"5\"", "[]", "null",
        ])
        .prop_map(str::to_string),
    ]
}

/// One of `usual`, or one of `odd`.
fn pick(usual: &[&'static str], odd: &[&'static str], e: u32) -> impl Strategy<Value = &'static str> {
    prop_oneof![USUAL => prop::sample::select(usual.to_vec()), e => prop::sample::select(odd.to_vec())]
}

/// `key: value, ` for a flow mapping, or now and then nothing: the default, or a missing
/// required key.
fn maybe(key: &'static str, value: impl Strategy<Value = String>, e: u32) -> impl Strategy<Value = String> {
    prop_oneof![USUAL => value.prop_map(move |v| format!("{key}: {v}, ")), e => Just(String::new())]
}

fn flow(parts: &[String]) -> String {
    format!("{{ {} }}", parts.concat().trim_end_matches([',', ' ']))
}

fn tower(e: u32) -> impl Strategy<Value = String> {
    let count = || prop_oneof![USUAL => (3usize..=8).prop_map(|n| n.to_string()), 4 * e => count(e)];
    (
        maybe("struts", count(), e),
        maybe("stages", count(), e),
        maybe("radius", length(e), e),
        maybe("strut_length", length(e), e),
        maybe("overlap", value(0.0..0.5, e), e),
    )
        .prop_map(|(a, b, c, d, o)| format!("model:\n  tower: {}\n", flow(&[a, b, c, d, o])))
}

/// Node groups of every model: a tower has the first three, an explicit model all four.
const GROUPS: [&str; 4] = ["base", "middle", "top", "g"];

/// An id of one of `count` nodes, or (rarely) one that repeats or names no node.
fn node_ref(count: usize, e: u32) -> impl Strategy<Value = String> {
    prop_oneof![
        USUAL => (0..count.max(1)).prop_map(|i| format!("n{i}")),
        e => prop::sample::select(vec!["n0", "zz"]).prop_map(str::to_string),
    ]
}

/// Explicit node and member lists: a consistent model (nodes on a ring, each joined to
/// the next two) with extreme coordinates, lengths and supports here and there, or lists
/// scrambled at random (repeated ids, unknown or equal ends, coincident or far-flung
/// nodes, groups naming unknown nodes).
fn explicit(e: u32) -> impl Strategy<Value = String> {
    prop_oneof![3 => consistent(e), 1 => scrambled(e)]
}

fn consistent(e: u32) -> impl Strategy<Value = String> {
    (3usize..=8).prop_flat_map(move |count| {
        let node = (
            prop_oneof![USUAL => Just(None), e => prop::array::uniform3(extreme(e)).prop_map(Some)],
            prop_oneof![USUAL => Just(vec![]), e => prop::collection::vec(prop::sample::select(vec!["x", "y", "z"]), 0..=3)],
        );
        let member = (
            prop::sample::select(vec!["strut", "cable"]),
            prop_oneof![USUAL => length(e).prop_map(Some), e => Just(None)],
        );
        (
            length(e),
            prop::collection::vec(node, count),
            prop::collection::vec(member, 2 * count),
        )
            .prop_map(move |(radius, nodes, members)| {
                let radius: f64 = radius.parse().unwrap_or(1.0);
                let mut s = String::from("model:\n  nodes:\n");
                for (i, (moved, fix)) in nodes.into_iter().enumerate() {
                    let a = std::f64::consts::TAU * i as f64 / count as f64;
                    let xyz = moved.unwrap_or([radius * a.cos(), radius * a.sin(), (i % 2) as f64]);
                    // Held against rigid-body motion by the first three nodes, and
                    // wherever else drawn.
                    let fix = match i {
                        0 | 1 => "x, y, z".to_string(),
                        2 => "z".to_string(),
                        _ => fix.join(", "),
                    };
                    s += &format!("    - {{ id: n{i}, xyz: [{}], fix: [{fix}] }}\n", xyz.map(float).join(", "));
                }
                s += "  members:\n";
                // Each node to the next two, every pair once.
                let mut pairs: Vec<(usize, usize)> = Vec::new();
                for (i, skip) in (1..=2).flat_map(|skip| (0..count).map(move |i| (i, skip))) {
                    let (p, q) = (i, (i + skip) % count);
                    if !pairs.contains(&(p, q)) && !pairs.contains(&(q, p)) {
                        pairs.push((p, q));
                    }
                }
                for (k, ((p, q), (kind, rest))) in pairs.into_iter().zip(members).enumerate() {
                    let rest = rest.map(|r| format!(", rest_length: {r}")).unwrap_or_default();
                    s += &format!("    - {{ id: m{k}, nodes: [n{p}, n{q}], kind: {kind}{rest} }}\n");
                }
                s += &format!("  groups: {{ base: [n0, n1], middle: [n2], top: [n{}], g: [n1, n2] }}\n", count - 1);
                s
            })
    })
}

fn scrambled(e: u32) -> impl Strategy<Value = String> {
    (0usize..=8).prop_flat_map(move |count| {
        let coordinate = prop_oneof![4 => (-3i32..=3).prop_map(f64::from), 1 => extreme(e)];
        let node = (
            prop::array::uniform3(coordinate),
            prop::collection::vec(prop::sample::select(vec!["x", "y", "z"]), 0..=3),
            prop::bool::weighted(0.05),
        );
        let nodes = prop::collection::vec(node, count).prop_map(|nodes| {
            nodes
                .into_iter()
                .enumerate()
                .map(|(i, (xyz, fix, repeat))| {
                    let id = if repeat { "n0".to_string() } else { format!("n{i}") };
                    format!(
                        "    - {{ id: {id}, xyz: [{}], fix: [{}] }}\n",
                        xyz.map(float).join(", "),
                        fix.join(", ")
                    )
                })
                .collect::<String>()
        });
        let member = (
            (node_ref(count, e), node_ref(count, e)),
            prop::sample::select(vec!["strut", "cable"]),
            prop::option::weighted(0.8, length(e)),
            prop::collection::vec(prop::sample::select(vec!["ring", "side"]), 0..=1),
            prop::bool::weighted(0.05),
        );
        let members = prop::collection::vec(member, 0..=3 * count).prop_map(|members| {
            members
                .into_iter()
                .enumerate()
                .map(|(k, ((p, q), kind, rest, groups, repeat))| {
                    let id = if repeat { "m0".to_string() } else { format!("m{k}") };
                    let rest = rest.map(|r| format!(", rest_length: {r}")).unwrap_or_default();
                    format!(
                        "    - {{ id: {id}, nodes: [{p}, {q}], kind: {kind}, groups: [{}]{rest} }}\n",
                        groups.join(", ")
                    )
                })
                .collect::<String>()
        });
        let group = (
            prop::sample::select(GROUPS.to_vec()),
            prop::collection::vec(node_ref(count, e), 0..=4),
        )
            .prop_map(|(g, ids)| format!("    {g}: [{}]\n", ids.join(", ")));
        let groups = prop::collection::vec(group, 0..=3).prop_map(|g| g.concat());
        (nodes, members, groups).prop_map(|(nodes, members, groups)| {
            let mut s = String::from("model:\n");
            for (key, items) in [("nodes", nodes), ("members", members), ("groups", groups)] {
                if !items.is_empty() {
                    s += &format!("  {key}:\n{items}");
                }
            }
            s
        })
    })
}

fn transient(name: &'static str, e: u32) -> impl Strategy<Value = String> {
    (
        maybe("duration", value(0.01..0.5, e), e),
        maybe("dt", value(0.0005..0.01, e), e),
        maybe("max_cuts", count(e), e),
        maybe("damped", pick(&["false"], &["true"], e).prop_map(str::to_string), e),
        pick(&GROUPS[..3], &["g", "nowhere"], e),
        extreme(e),
        value(0.001..0.1, e),
    )
        .prop_map(move |(d, dt, cuts, damped, group, force, load)| {
            let load = format!(
                "load: {{ groups: [{group}], force: [0.0, 0.0, {}], duration: {load} }}",
                float(force)
            );
            format!("{name}: {}\n", flow(&[d, dt, cuts, damped, load]))
        })
}

/// Every section around the model, each present or not, with edge values.
fn sections(e: u32) -> impl Strategy<Value = String> {
    let material = || {
        pick(
            &["aluminium", "steel", "cfrp", "rubber", "nylon", "steel_cable"],
            &["unobtainium"],
            e,
        )
    };
    let formfinding = prop_oneof![
        USUAL => (maybe("strut_ea", length(e), e), maybe("cable_n", value(1.0..4.0, e), e), length(e)).prop_map(|(ea, n, c)| {
            Some(format!(
                "formfinding: {{ measure: {} }}\n",
                flow(&[ea, n, format!("cable_c: {{ uniform: {c} }}")])
            ))
        }),
        e => Just(None),
    ];
    let substitution = (material(), material(), maybe("prestress_scale", length(e), e))
        .prop_map(|(s, c, p)| format!("substitution: {}\n", flow(&[format!("strut: {s}, cable: {c}, "), p])));
    let eigen = prop::option::of(prop_oneof![
        (count(e), count(e), value(0.0..0.9, e))
            .prop_map(|(i, j, z)| format!("eigen: {{ rayleigh: {{ modes: [{i}, {j}], ratios: [{z}, 0.1] }} }}\n")),
        (length(e), length(e)).prop_map(|(a, b)| format!("eigen: {{ rayleigh: {{ alpha: {a}, beta: {b} }} }}\n")),
    ]);
    let folding = prop::option::of(
        (maybe("steps", count(e), e), pick(&GROUPS[..3], &["g", "nowhere"], e), extreme(e)).prop_map(|(steps, g, d)| {
            format!(
                "folding: {}\n",
                flow(&[steps, format!("prescribe: [{{ group: {g}, axis: z, displacement: {} }}]", float(d))])
            )
        }),
    );
    let newton = prop::option::weighted(
        0.3,
        (maybe("max_iterations", count(e), e), maybe("force_tolerance", length(e), e))
            .prop_map(|(i, f)| format!("newton: {}\n", flow(&[i, f]))),
    );
    let outputs = prop::option::weighted(0.3, count(e).prop_map(|n| format!("outputs: {{ every: {n} }}\n")));
    let limits = prop::option::weighted(
        0.2,
        (
            maybe("max_output_gb", length(e), e),
            maybe("max_memory_gb", length(e), e),
            maybe("max_steps", count(e), e),
        )
            .prop_map(|(o, m, s)| format!("limits: {}\n", flow(&[o, m, s]))),
    );
    (
        formfinding,
        substitution,
        prop::sample::select(vec!["paper", "physical"]),
        eigen,
        prop::option::of(transient("free_vibration", e)),
        folding,
        prop::option::of(transient("deployment", e)),
        newton,
        outputs,
        limits,
    )
        .prop_map(|(ff, sub, masses, eig, fv, fold, dep, newton, out, lim)| {
            [
                ff,
                Some(sub),
                Some(format!("masses: {masses}\n")),
                eig,
                fv,
                fold,
                dep,
                newton,
                out,
                lim,
            ]
            .into_iter()
            .flatten()
            .collect()
        })
}

/// Whether an error says where: every value error has a line, a parser error names one.
fn located(e: &ConfigError) -> bool {
    match e {
        ConfigError::Values(errors) => errors.iter().all(|v| v.line.is_some()),
        ConfigError::Syntax { line, .. } => line.is_some(),
        ConfigError::Io { .. } => false,
    }
}

/// The runner's settings; failures of the test `file` are persisted in
/// `tests/proptest-regressions/<file>.txt`.
fn config(file: &'static str) -> Config {
    let cases = std::env::var("TSIM_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(CASES);
    let seed = std::env::var("PROPTEST_RNG_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0x7e51_f022);
    Config {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct(file))),
        source_file: Some(file!()),
        // Bounds the time a failure spends shrinking.
        max_shrink_iters: 2048,
        ..Config::default()
    }
}

/// Runs configs built around `models` (each with every section around it, and with or
/// without `--allow-large`) through `tsim check`'s path; returns (accepted, rejected).
fn check_all<S: Strategy<Value = String>>(name: &str, corpus: &'static str, models: fn(u32) -> S) -> (usize, usize) {
    let configs = prop_oneof![Just(1_u32), Just(10)]
        .prop_flat_map(move |e| (pick(&["fuzz"], &["../escape", "", "a b"], e), models(e), sections(e), any::<bool>()));
    let (accepted, rejected) = (Cell::new(0), Cell::new(0));
    let started = std::time::Instant::now();
    let mut runner = TestRunner::new(config(corpus));
    let result = runner.run(&configs, |(name, model, sections, allow_large)| {
        let text = format!("name: \"{name}\"\n{model}{sections}");
        match expand(&text, "fuzz.yaml", allow_large) {
            Ok(expanded) => {
                accepted.set(accepted.get() + 1);
                for c in &expanded.cases {
                    let e = &c.estimate;
                    prop_assert!(
                        e.output.is_finite() && e.output >= 0.0 && e.memory.is_finite() && e.memory > 0.0,
                        "estimate {e:?} of\n{text}"
                    );
                }
            }
            Err(e) => {
                rejected.set(rejected.get() + 1);
                if std::env::var_os("TSIM_FUZZ_SHOW").is_some() {
                    eprintln!("{}", e.to_string().lines().next().unwrap_or_default());
                }
                if !located(&e) {
                    return Err(TestCaseError::fail(format!("a rejection without a line: {e}\nof\n{text}")));
                }
            }
        }
        Ok(())
    });
    eprintln!(
        "{name}: {} configs in {:.2} s: {} accepted, {} rejected",
        runner.config().cases,
        started.elapsed().as_secs_f64(),
        accepted.get(),
        rejected.get()
    );
    if let Err(e) = result {
        panic!("{name}: {e}");
    }
    (accepted.get(), rejected.get())
}

#[test]
fn generated_towers_never_panic_and_every_rejection_has_a_line() {
    let (accepted, rejected) = check_all(
        "towers",
        concat!(env!("CARGO_MANIFEST_DIR"), "/tests/proptest-regressions/towers.txt"),
        tower,
    );
    // Some configs must get through validation, or the test only exercises the parser.
    assert!(accepted > 0 && rejected > 0, "{accepted} accepted, {rejected} rejected");
}

#[test]
fn generated_node_lists_never_panic_and_every_rejection_has_a_line() {
    let (accepted, rejected) = check_all(
        "node lists",
        concat!(env!("CARGO_MANIFEST_DIR"), "/tests/proptest-regressions/node_lists.txt"),
        explicit,
    );
    assert!(accepted > 0 && rejected > 0, "{accepted} accepted, {rejected} rejected");
}

/// An axis name or value label: ordinary (`usual`, a regex), or any of the strings that once escaped --out
/// or broke a run (issue 29: separators, `..`, absolute paths, control characters, empty,
/// 300 and 70 000 characters, non-ASCII).
fn label_text(usual: &'static str, e: u32) -> impl Strategy<Value = String> {
    prop_oneof![
        USUAL => usual,
        e => prop::sample::select(vec![
            "", ".", "..", "../../victim", "/tmp/x", "a/b", "a\\b", "a\nb", "a\u{0}b", "é", "a b", "-", "_", "a-b", "a_b",
        ])
        .prop_map(str::to_string),
        e => "[ -~]{0,40}",
        e => prop::sample::select(vec![300_usize, 70_000]).prop_map(|n| "9".repeat(n)),
    ]
}

/// Sweeps of 1–3 axes of 1–3 values with generated names and labels, through `tsim
/// check`'s path over the small sweep fixture's base: none may panic, every rejection
/// says where, and every case id an accepted sweep makes is one plain directory name
/// (no separator, not `.` or `..`, at most 200 bytes), so that no case writes outside
/// --out.
#[test]
fn generated_sweep_names_stay_inside_the_run_directory() {
    let fixture = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/small_sweep.yaml")).unwrap();
    let base = fixture.split("sweep:").next().unwrap().to_string();
    let axes = prop_oneof![Just(1_u32), Just(10)].prop_flat_map(|e| {
        let name = label_text("[a-z][a-z0-9_]{0,10}", e);
        let label = label_text("[a-z0-9][a-z0-9.-]{0,10}", e);
        prop::collection::vec((name, prop::collection::vec(label, 1..=3)), 1..=3)
    });
    let (accepted, rejected) = (Cell::new(0), Cell::new(0));
    let mut runner = TestRunner::new(config(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/proptest-regressions/sweep_names.txt"
    )));
    let result = runner.run(&axes, |axes| {
        let mut text = format!("{base}sweep:\n  axes:\n");
        for (name, labels) in &axes {
            // JSON strings are YAML double-quoted scalars: any text, escaped.
            text += &format!("    - name: {}\n      values:\n", serde_json::to_string(name).unwrap());
            for l in labels {
                text += &format!(
                    "        - {{ label: {}, set: {{ outputs.every: 1 }} }}\n",
                    serde_json::to_string(l).unwrap()
                );
            }
        }
        match expand(&text, "fuzz.yaml", false) {
            Ok(expanded) => {
                accepted.set(accepted.get() + 1);
                for c in &expanded.cases {
                    let mut parts = std::path::Path::new(&c.id).components();
                    let plain = matches!(parts.next(), Some(std::path::Component::Normal(_))) && parts.next().is_none();
                    prop_assert!(plain && !c.id.contains('/') && c.id.len() <= 200, "case id {:?} of\n{text}", c.id);
                }
            }
            Err(e) => {
                rejected.set(rejected.get() + 1);
                prop_assert!(located(&e), "a rejection without a line: {e}\nof\n{text}");
            }
        }
        Ok(())
    });
    eprintln!("sweep names: {} accepted, {} rejected", accepted.get(), rejected.get());
    if let Err(e) = result {
        panic!("sweep names: {e}");
    }
    assert!(
        accepted.get() > 0 && rejected.get() > 0,
        "{} accepted, {} rejected",
        accepted.get(),
        rejected.get()
    );
}
