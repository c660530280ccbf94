//! Finds the line of a dotted field path (`deployment.dt`, `eigen.rayleigh.modes[1]`) in
//! the YAML text, so that value errors point at the line like parse errors do. A light
//! scan, not a parser: it follows block mappings by indentation and flow mappings
//! (`{ key: ... }`) on one line, which covers the configs tsim reads; when it cannot
//! find a key it returns the line of the deepest key it found.

/// 1-based line of `path`, or of its deepest prefix present; `None` if not even the first key is.
pub fn line_of(text: &str, path: &str) -> Option<usize> {
    // Each key with the index that follows it (`loads[1]`: the second item).
    let keys: Vec<(&str, Option<usize>)> = path
        .split('.')
        .map(|k| {
            let mut parts = k.split('[');
            let key = parts.next().unwrap_or(k);
            (key, parts.next().and_then(|i| i.trim_end_matches(']').parse().ok()))
        })
        .filter(|(k, _)| !k.is_empty())
        .collect();
    let lines: Vec<&str> = text.lines().collect();
    let indent = |l: &str| l.len() - l.trim_start().len();
    let is_content = |l: &str| !l.trim().is_empty() && !l.trim_start().starts_with('#');
    // (line index, column after the key) of the last key found; the scope of the next key
    // is the rest of that line plus the following lines indented deeper than it.
    let mut found: Option<(usize, usize, usize)> = None; // (line, column, indent of the key's line)
    for (key, index) in keys {
        let pattern = format!("{key}:");
        let hit = match found {
            None => lines
                .iter()
                .enumerate()
                .find(|(_, l)| indent(l) == 0 && l.starts_with(&pattern))
                .map(|(i, _)| (i, pattern.len(), 0)),
            Some((line, col, ind)) => {
                let same = key_in(&lines[line][col..], key).map(|c| (line, col + c, ind));
                same.or_else(|| {
                    lines[line + 1..]
                        .iter()
                        .enumerate()
                        .take_while(|(_, l)| !is_content(l) || indent(l) > ind)
                        .find_map(|(k, l)| key_in(l, key).map(|c| (line + 1 + k, c, indent(l))))
                })
            }
        };
        match hit {
            Some(h) => found = Some(index.and_then(|k| item(&lines, h, k)).unwrap_or(h)),
            None => break,
        }
    }
    found.map(|(line, _, _)| line + 1)
}

/// The `k`-th item (0-based) of a block sequence that is the value of the key found at
/// `(line, column, indent)`: its `- ` line, the column after the dash and the dash's
/// indent. `None` for a flow sequence or fewer items (the key's line is used then).
fn item(lines: &[&str], (line, col, ind): (usize, usize, usize), k: usize) -> Option<(usize, usize, usize)> {
    let rest = lines[line][col..].trim();
    if !(rest.is_empty() || rest.starts_with('#')) {
        return None;
    }
    let indent = |l: &str| l.len() - l.trim_start().len();
    let content = |l: &&str| !l.trim().is_empty() && !l.trim_start().starts_with('#');
    let (first, _) = lines.iter().enumerate().skip(line + 1).find(|(_, l)| content(l))?;
    let dash = indent(lines[first]);
    if dash < ind || !lines[first].trim_start().starts_with('-') {
        return None;
    }
    lines
        .iter()
        .enumerate()
        .skip(first)
        .filter(|(_, l)| content(l))
        .take_while(|(_, l)| indent(l) > dash || (indent(l) == dash && l.trim_start().starts_with('-')))
        .filter(|(_, l)| indent(l) == dash)
        .nth(k)
        .map(|(i, _)| (i, dash + 1, dash))
}

/// Column just after `key:` in `s`, where the key starts a mapping entry (line start,
/// after `{`, `,` or `- `).
fn key_in(s: &str, key: &str) -> Option<usize> {
    let pattern = format!("{key}:");
    let mut from = 0;
    while let Some(pos) = s[from..].find(&pattern) {
        let at = from + pos;
        let before = s[..at].trim_end();
        if before.is_empty() || before.ends_with('{') || before.ends_with(',') || before.ends_with('-') {
            return Some(at + pattern.len());
        }
        from = at + pattern.len();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::line_of;

    const TEXT: &str = "name: x\nmodel:\n  tower: { struts: 5, radius: 3.0 }\n# comment\ndeployment:\n  duration: 8.0\n  dt: -1\n  load: { groups: [top], force: [0, 0, 1] }\neigen:\n  rayleigh:\n    modes: [3, 99]\n";

    #[test]
    fn finds_block_and_flow_keys() {
        assert_eq!(line_of(TEXT, "deployment.dt"), Some(7));
        assert_eq!(line_of(TEXT, "model.tower.radius"), Some(3));
        assert_eq!(line_of(TEXT, "eigen.rayleigh.modes[1]"), Some(11));
        assert_eq!(line_of(TEXT, "deployment.load.groups"), Some(8));
        // A key that is absent (a default): the line of its section.
        assert_eq!(line_of(TEXT, "deployment.newmark_beta"), Some(5));
        assert_eq!(line_of(TEXT, "folding.steps"), None);
        // Items of a block sequence by index, nested keys inside them.
        let loads = "deployment:\n  loads:\n    - nodes: [a]\n      time: { step: { duration: 1 } }\n    - groups: [top]\n      # a comment\n      time:\n        ramp: { duration: -1 }\n  dt: 1\n";
        assert_eq!(line_of(loads, "deployment.loads[1].time.ramp.duration"), Some(8));
        assert_eq!(line_of(loads, "deployment.loads[0].time"), Some(4));
        assert_eq!(line_of(loads, "deployment.loads[1]"), Some(5));
        // Past the last item: the sequence's key.
        assert_eq!(line_of(loads, "deployment.loads[2]"), Some(2));
        // `dt` inside another section is not taken for `deployment.dt`.
        assert_eq!(
            line_of("free_vibration:\n  dt: 1\ndeployment:\n  dt: 2\n", "deployment.dt"),
            Some(4)
        );
    }
}
