//! Finds the line of a dotted field path (`deployment.dt`, `eigen.rayleigh.modes[1]`) in
//! the YAML text, so that value errors point at the line like parse errors do. A light
//! scan, not a parser: it follows block mappings by indentation and flow mappings
//! (`{ key: ... }`) on one line, which covers the configs tsim reads; when it cannot
//! find a key it returns the line of the deepest key it found.

/// 1-based line of `path`, or of its deepest prefix present; `None` if not even the first key is.
pub fn line_of(text: &str, path: &str) -> Option<usize> {
    let keys: Vec<&str> = path
        .split('.')
        .map(|k| k.split('[').next().unwrap_or(k))
        .filter(|k| !k.is_empty())
        .collect();
    let lines: Vec<&str> = text.lines().collect();
    let indent = |l: &str| l.len() - l.trim_start().len();
    let is_content = |l: &str| !l.trim().is_empty() && !l.trim_start().starts_with('#');
    // (line index, column after the key) of the last key found; the scope of the next key
    // is the rest of that line plus the following lines indented deeper than it.
    let mut found: Option<(usize, usize, usize)> = None; // (line, column, indent of the key's line)
    for key in keys {
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
            Some(h) => found = Some(h),
            None => break,
        }
    }
    found.map(|(line, _, _)| line + 1)
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
        // `dt` inside another section is not taken for `deployment.dt`.
        assert_eq!(
            line_of("free_vibration:\n  dt: 1\ndeployment:\n  dt: 2\n", "deployment.dt"),
            Some(4)
        );
    }
}
