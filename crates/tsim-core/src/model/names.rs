//! "Did you mean": the known name closest to a misspelt one (edit distance at most 2,
//! a name typed short of a known one, or the same letters but for case, `_` and `-`).

/// The known name closest to `name`, if one is close enough to be the one meant.
pub fn closest<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let squash = |s: &str| s.to_lowercase().replace(['_', '-'], "");
    let len = name.chars().count();
    known
        .into_iter()
        .filter(|k| *k != name)
        .filter_map(|k| {
            let d = strsim::levenshtein(name, k);
            // Ranked: the same but for spelling of separators, then typed short, then by distance.
            let (same, short) = (squash(k) == squash(name), len >= 3 && k.starts_with(name));
            let rank = if same {
                0
            } else if short {
                1
            } else {
                d
            };
            (same || short || (d <= 2 && d < len)).then_some((rank, k))
        })
        .min_by_key(|&(d, _)| d)
        .map(|(_, k)| k)
}

/// ` (did you mean `x`?)`, or nothing when no known name is close.
pub fn hint<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> String {
    closest(name, known).map_or_else(String::new, |k| format!(" (did you mean `{k}`?)"))
}

#[cfg(test)]
mod tests {
    use super::closest;

    #[test]
    fn close_names_only() {
        let keys = ["masses", "materials", "name", "strut_length", "rest_length"];
        assert_eq!(closest("massess", keys), Some("masses"));
        assert_eq!(closest("restlength", keys), Some("rest_length"));
        assert_eq!(closest("mat", keys), Some("materials"));
        assert_eq!(closest("Strut-Length", keys), Some("strut_length"));
        assert_eq!(closest("aluminum", ["aluminium", "steel"]), Some("aluminium"));
        assert_eq!(closest("tops", ["base", "top"]), Some("top"));
        assert_eq!(closest("x", ["y", "z"]), None);
        assert_eq!(closest("gravity", keys), None);
    }
}
