//! Mutation testing of the config loader and model builder: seed configs (configs/,
//! tests/fixtures/ and the reproducers in tests/corpus/) are mutated deterministically —
//! numbers replaced by edge values, lines dropped, doubled or cut, keys swapped, stray
//! punctuation, paths and names (a table `file:`, a `name:`, a `label:`) replaced by
//! hostile ones, anchors and aliases between values (tests/corpus/alias_bomb.yaml seeds
//! an alias bomb) — and each mutant goes through sweep expansion and validation, which
//! builds every case's model. No mutant may panic or hang (a table at /dev/zero), every
//! rejection must say where: a line (`file:N:`, a parse error's `file:N:M:`), and every
//! case an accepted one makes is one plain directory name. A bounded run here (3000 mutants, a few
//! seconds); `TSIM_MUTANTS=N` runs more, and `TSIM_MUTANTS_DIR=dir` also writes every
//! mutant there, for a campaign (scripts/campaign): `dir/<seed's directory>/m<k>-<seed>-
//! <ok|no>.yaml`, beside where its seed's tables would be, with the verdict.

use std::panic::{catch_unwind, AssertUnwindSafe};
use tsim::config::ConfigError;
use tsim::run::expand;

/// xorshift64*: deterministic, so a failure names a reproducible mutant.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const EDGE_VALUES: [&str; 16] = [
    "0",
    "-1",
    "1",
    "0.0",
    "-0.0",
    "1.0e308",
    "-1.0e308",
    "1.0e-300",
    ".nan",
    ".inf",
    "-.inf",
    "4294967296",
    "18446744073709551616",
    "3.5",
    "\"\"",
    "[]",
];
const PUNCTUATION: [&str; 8] = [":", "{", "}", "[", "]", ",", "- ", "\""];
/// Paths and names that reached outside --out or the config's directory, or hung or
/// exhausted a run (issue 29), for the scalar after a `file:`, `name:` or `label:` key.
const HOSTILE: [&str; 9] = [
    "/dev/zero",
    "/etc/passwd",
    "../../../../etc/hostname",
    "/tmp",
    "\"../../victim\"",
    "\"/abs/path\"",
    "\"a\\nb\"",
    "\"\"",
    "\"a/b\"",
];
/// The keys whose value is a path or becomes one.
const PATH_KEYS: [&str; 3] = ["file: ", "name: ", "label: "];

fn seeds() -> Vec<(String, String)> {
    let root = env!("CARGO_MANIFEST_DIR");
    ["configs", "configs/examples", "tests/fixtures", "tests/corpus"]
        .iter()
        .flat_map(|dir| std::fs::read_dir(format!("{root}/{dir}")).unwrap())
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .map(|p| (p.display().to_string(), std::fs::read_to_string(&p).unwrap()))
        .collect()
}

/// One mutation of `text`.
fn mutate(text: &str, rng: &mut Rng) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    if lines.is_empty() {
        return text.to_string();
    }
    let i = rng.below(lines.len());
    match rng.below(8) {
        0 => {
            // A number (or any scalar after `: `) replaced by an edge value.
            let tokens: Vec<(usize, usize)> = number_spans(&lines[i]);
            if let Some(&(a, b)) = tokens.get(rng.below(tokens.len())) {
                lines[i].replace_range(a..b, EDGE_VALUES[rng.below(EDGE_VALUES.len())]);
            }
        }
        1 => {
            lines.remove(i);
        }
        2 => {
            let l = lines[i].clone();
            lines.insert(i, l);
        }
        3 => {
            let cut = floor_char(&lines[i], rng.below(lines[i].len() + 1));
            lines[i].truncate(cut);
        }
        4 => {
            let at = floor_char(&lines[i], rng.below(lines[i].len() + 1));
            lines[i].insert_str(at, PUNCTUATION[rng.below(PUNCTUATION.len())]);
        }
        5 => {
            // The value of a path-like key replaced by a hostile path or name.
            if let Some((key, at)) = PATH_KEYS.iter().find_map(|k| lines[i].find(k).map(|at| (k, at))) {
                let start = at + key.len();
                let end = lines[i][start..].find([',', '}']).map_or(lines[i].len(), |e| start + e);
                lines[i].replace_range(start..end, HOSTILE[rng.below(HOSTILE.len())]);
            }
        }
        6 => {
            // An anchor on one value and an alias to it in place of a later value (the
            // alias may stand for a value of another type, or precede its anchor when the
            // later line is the one anchored).
            let j = rng.below(lines.len());
            if let (Some((a, b)), Some((c, d))) = (value_span(&lines[i]), value_span(&lines[j])) {
                if i != j {
                    lines[j].replace_range(c..d, "*mutant");
                    lines[i].insert_str(a.min(b), "&mutant ");
                }
            }
        }
        _ => {
            // A line of another place in the file moved here (keys in the wrong section).
            let j = rng.below(lines.len());
            lines.swap(i, j);
        }
    }
    lines.join("\n") + "\n"
}

/// The byte span of the value after a line's first `: ` (to the next `,` or `}`, or the
/// line's end), if it has one.
fn value_span(line: &str) -> Option<(usize, usize)> {
    let start = line.find(": ")? + 2;
    let end = line[start..].find([',', '}']).map_or(line.len(), |e| start + e);
    (start < end).then_some((start, end))
}

fn floor_char(s: &str, mut at: usize) -> usize {
    while !s.is_char_boundary(at) {
        at -= 1;
    }
    at
}

/// Byte spans of the numbers in a line.
fn number_spans(line: &str) -> Vec<(usize, usize)> {
    let bytes = line.as_bytes();
    let mut spans = Vec::new();
    let mut k = 0;
    while k < bytes.len() {
        let start_ok = k == 0 || !bytes[k - 1].is_ascii_alphanumeric() && bytes[k - 1] != b'_';
        if bytes[k].is_ascii_digit() && start_ok {
            let a = k;
            while k < bytes.len() && (bytes[k].is_ascii_alphanumeric() || matches!(bytes[k], b'.' | b'-' | b'+')) {
                k += 1;
            }
            spans.push((a, k));
        } else {
            k += 1;
        }
    }
    spans
}

/// Whether an error says where: every value error has a line, a parser error names one.
/// Writes mutant `k` of the seed `origin` for a campaign, when `TSIM_MUTANTS_DIR` is set.
fn keep(k: usize, origin: &str, text: &str, verdict: &str) {
    let Ok(dir) = std::env::var("TSIM_MUTANTS_DIR") else { return };
    let seed = std::path::Path::new(origin);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let at = std::path::Path::new(&dir).join(seed.parent().unwrap().strip_prefix(root).unwrap());
    std::fs::create_dir_all(&at).unwrap();
    let stem = seed.file_stem().unwrap().to_string_lossy();
    std::fs::write(at.join(format!("m{k:06}-{stem}-{verdict}.yaml")), text).unwrap();
}

fn located(e: &ConfigError) -> bool {
    match e {
        ConfigError::Values(errors) => errors.iter().all(|v| v.line.is_some()),
        ConfigError::Syntax { line, .. } => line.is_some(),
        ConfigError::Io { .. } => false,
    }
}

#[test]
fn mutated_configs_never_panic_and_every_rejection_has_a_line() {
    let seeds = seeds();
    let count: usize = std::env::var("TSIM_MUTANTS").ok().and_then(|v| v.parse().ok()).unwrap_or(3000);
    let mut rng = Rng(0x7e51_6d00_5eed_0001);
    let (mut accepted, mut rejected) = (0, 0);
    let mut unlocated = Vec::new();
    let started = std::time::Instant::now();
    for k in 0..count {
        let (origin, seed) = &seeds[rng.below(seeds.len())];
        let mut text = seed.clone();
        for _ in 0..1 + rng.below(3) {
            text = mutate(&text, &mut rng);
        }
        let result = catch_unwind(AssertUnwindSafe(|| expand(&text, origin, false)));
        match result {
            Err(_) => panic!("mutant {k} of {origin} panicked:\n{text}"),
            Ok(Ok(expanded)) => {
                accepted += 1;
                // Every case directory is one plain name under the run's.
                for c in &expanded.cases {
                    let mut parts = std::path::Path::new(&c.id).components();
                    let plain = matches!(parts.next(), Some(std::path::Component::Normal(_))) && parts.next().is_none();
                    assert!(plain, "mutant {k} of {origin}: case id {:?}\n{text}", c.id);
                }
                keep(k, origin, &text, "ok");
            }
            Ok(Err(e)) => {
                keep(k, origin, &text, "no");
                rejected += 1;
                if !located(&e) && unlocated.len() < 5 {
                    unlocated.push(format!("mutant {k} of {origin}: {e}\n{text}"));
                }
            }
        }
    }
    eprintln!(
        "{count} mutants in {:.1} s: {accepted} accepted, {rejected} rejected",
        started.elapsed().as_secs_f64()
    );
    assert!(unlocated.is_empty(), "rejections without a line:\n{}", unlocated.join("\n---\n"));
    // The mutations must reach validation, not only the parser: some mutants stay valid.
    assert!(
        accepted > count / 20 && rejected > count / 4,
        "{accepted} accepted, {rejected} rejected"
    );
}
