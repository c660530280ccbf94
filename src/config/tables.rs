//! Time tables from CSV files: `time: {table: {file: rec.csv}}` is read, relative to the
//! config file's directory, into the table's `points` when the config is loaded, so that
//! no later step touches the file. The cases of a sweep share the points read, and the run
//! keeps one copy of each table in its `tables/` directory, named by its CRC-32, which
//! every `case.yaml` names: the resolved config still says exactly what the case ran with
//! (and runs as it is), without a copy of a 10⁶-row record in each of 1000 cases.

use super::input::{excerpt, read_input};
use super::loading::{TablePoints, TimeFunctionSpec};
use super::schema::CaseConfig;
use super::validate::{FieldError, ValueError};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A table that could not be read: a field of the config (the file is missing, located
/// by the caller at the field's line) or a line of the CSV file.
#[derive(Clone, Debug, PartialEq)]
pub enum TableError {
    Field(FieldError),
    Csv(ValueError),
}

impl CaseConfig {
    /// Every time function of the config with its dotted field path.
    fn time_functions_mut(&mut self) -> Vec<(String, &mut TimeFunctionSpec)> {
        let mut out = Vec::new();
        for (name, t) in self.transients_mut() {
            for (k, l) in t.loads.iter_mut().enumerate() {
                out.push((format!("{name}.loads[{k}].time"), &mut l.time));
            }
            if let Some(g) = &mut t.ground_motion {
                out.push((format!("{name}.ground_motion.time"), &mut g.time));
            }
            for (k, a) in t.actuation.iter_mut().enumerate() {
                out.push((format!("{name}.actuation[{k}].time"), &mut a.time));
            }
        }
        out
    }

    /// Reads every table given by `file` (relative to `dir`) into its `points` and drops
    /// the file name; reports every problem of every table. A file `read` holds already is
    /// shared, not read again.
    pub fn resolve_tables(&mut self, dir: &Path, read: &mut TableFiles) -> Result<(), Vec<TableError>> {
        let mut errors = Vec::new();
        let allowed = self.table_directories(dir, &mut errors);
        for (field, spec) in self.time_functions_mut() {
            let TimeFunctionSpec::Table { file, points, kept_as } = spec else {
                continue;
            };
            // With both given, `validate` reports it; the file is not read.
            let (Some(name), true) = (file.as_ref(), points.is_empty()) else {
                continue;
            };
            let field = format!("{field}.table.file");
            let path = dir.join(name);
            if let Err(message) = inside(&path, &allowed) {
                errors.push(TableError::Field(FieldError { field, message }));
                continue;
            }
            if let Some((rows, kept)) = path.canonicalize().ok().and_then(|p| read.0.get(&p)) {
                (*points, *kept_as, *file) = (rows.clone(), Some(kept.clone()), None);
                continue;
            }
            let text = read_input(&path).and_then(|b| String::from_utf8(b).map_err(|_| "is not UTF-8 text; save it as UTF-8".into()));
            match text {
                Ok(text) => match parse_table(&text, &path.display().to_string(), &field) {
                    Ok(rows) => {
                        let rows: TablePoints = rows.into();
                        let kept: Arc<str> = kept_name(name, &rows).into();
                        read.0.extend(path.canonicalize().ok().map(|p| (p, (rows.clone(), kept.clone()))));
                        (*points, *kept_as, *file) = (rows, Some(kept), None);
                    }
                    Err(e) => errors.extend(e.into_iter().map(TableError::Csv)),
                },
                Err(e) => errors.push(TableError::Field(FieldError {
                    field,
                    message: format!(
                        "cannot read `{}`: {e}; the path is relative to the config file's directory",
                        path.display()
                    ),
                })),
            }
        }
        if errors.is_empty() {
            Ok(())
        } else {
            Err(errors)
        }
    }
}

/// The points of a config's tables, taken out by field (`CaseConfig::take_tables`) so that
/// the cases of a sweep share them: a sweep builds each case from a JSON copy of its base,
/// which would copy a table of 10⁶ rows into every case (a 1000-case sweep of one such
/// table asked for more memory than the machine had before any limit was checked).
#[derive(Clone, Debug, Default)]
pub struct SharedTables(Vec<(String, TablePoints, Option<Arc<str>>)>);

/// The table files read so far, by resolved path: the cases of a sweep that name one file
/// share its points.
#[derive(Debug, Default)]
pub struct TableFiles(std::collections::HashMap<PathBuf, (TablePoints, Arc<str>)>);

impl CaseConfig {
    /// Takes the points of every table with points out of the config, leaving them empty.
    pub fn take_tables(&mut self) -> SharedTables {
        let mut shared = SharedTables::default();
        for (field, spec) in self.time_functions_mut() {
            if let TimeFunctionSpec::Table { points, kept_as, .. } = spec {
                if !points.is_empty() {
                    shared.0.push((field, std::mem::take(points), kept_as.take()));
                }
            }
        }
        shared
    }

    /// Puts `shared` back into the tables it was taken from (sharing, not copying) where
    /// the table is still empty and no path of `set` (dotted, as a sweep sets them) reaches
    /// its field: a set table is the sweep's, not the base's.
    pub fn share_tables(&mut self, shared: &SharedTables, set: &[&str]) {
        for (field, spec) in self.time_functions_mut() {
            let TimeFunctionSpec::Table {
                file: None,
                points,
                kept_as,
            } = spec
            else {
                continue;
            };
            let Some((_, taken, kept)) = shared.0.iter().find(|(f, ..)| *f == field) else {
                continue;
            };
            if points.is_empty() && !set.iter().any(|path| reaches(path, &field)) {
                (*points, *kept_as) = (taken.clone(), kept.clone());
            }
        }
    }
}

/// Where a run keeps the tables its cases read from files, beside the case directories.
pub const KEPT_TABLES: &str = "tables";

impl CaseConfig {
    /// The config as `case.yaml` records it: each table read from a file named by the
    /// run's copy (`../tables/<name>`, allowed by `table_dirs`) instead of its rows.
    pub fn recorded(&self) -> CaseConfig {
        let mut out = self.clone();
        let mut kept = false;
        for (_, spec) in out.time_functions_mut() {
            if let TimeFunctionSpec::Table {
                file,
                points,
                kept_as: Some(name),
            } = spec
            {
                (*file, *points) = (Some(format!("../{KEPT_TABLES}/{name}")), Arc::default());
                kept = true;
            }
        }
        // The config's own `table_dirs` are relative to it, not to case.yaml.
        out.table_dirs = if kept { vec![format!("../{KEPT_TABLES}")] } else { Vec::new() };
        out
    }

    /// The tables the run keeps for this case: (file name, points).
    pub fn kept_tables(&self) -> Vec<(Arc<str>, TablePoints)> {
        self.tables()
            .into_iter()
            .filter_map(|(_, name, points)| Some((name?, points)))
            .collect()
    }

    /// Every table's points (shared with the other cases of a sweep that hold them).
    pub fn table_points(&self) -> Vec<TablePoints> {
        self.tables().into_iter().map(|(.., points)| points).collect()
    }

    /// Every table: its field, the name of the run's copy (read from a file), its points.
    pub(super) fn tables(&self) -> Vec<(String, Option<Arc<str>>, TablePoints)> {
        // A clone (the points are shared, not copied) to walk the one list of time
        // functions there is, the mutable one.
        let mut walked = self.clone();
        walked
            .time_functions_mut()
            .into_iter()
            .filter_map(|(field, spec)| match spec {
                TimeFunctionSpec::Table { points, kept_as, .. } => Some((field, kept_as.clone(), points.clone())),
                _ => None,
            })
            .collect()
    }
}

/// A table's points as the CSV the run keeps: `t,f` rows in the shortest decimals that
/// read back to the same numbers, so the copy gives the case exactly what it ran with.
pub fn table_csv(points: &[[f64; 2]]) -> String {
    let mut text = String::from("time,value\n");
    for [t, f] in points {
        text.push_str(&format!("{t:?},{f:?}\n"));
    }
    text
}

/// The name of the run's copy of a table read from the file `given`: its stem and the
/// CRC-32 of its CSV (`rec-1a2b3c4d.csv`), so that a changed table is another file and
/// another `case.yaml`. Reading a copy back gives its own name again.
fn kept_name(given: &str, points: &[[f64; 2]]) -> String {
    let crc = format!("{:08x}", zlib_rs::crc32::crc32(0, table_csv(points).as_bytes()));
    let stem = Path::new(given)
        .file_stem()
        .map_or_else(|| "table".into(), |s| s.to_string_lossy().into_owned());
    let stem = stem.strip_suffix(&format!("-{crc}")).unwrap_or(&stem);
    // A plain, bounded file name whatever the given one was.
    let safe = |c: char| {
        if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
            c
        } else {
            '_'
        }
    };
    let stem: String = stem.chars().take(64).map(safe).collect();
    format!("{stem}-{crc}.csv")
}

/// Whether setting the dotted `path` changes the time function at `field`
/// (`deployment.loads[0].time`): one holds the other.
fn reaches(path: &str, field: &str) -> bool {
    let within = |long: &str, short: &str| {
        long.strip_prefix(short)
            .is_some_and(|rest| rest.is_empty() || rest.starts_with(['.', '[']))
    };
    within(field, path) || within(path, field)
}

impl CaseConfig {
    /// The directories tables may be read from, resolved (links followed): `dir`, the
    /// config's, and those of `table_dirs`; one that does not resolve is an error of its field.
    fn table_directories(&self, dir: &Path, errors: &mut Vec<TableError>) -> Vec<PathBuf> {
        let mut allowed: Vec<PathBuf> = dir.canonicalize().into_iter().collect();
        for (k, d) in self.table_dirs.iter().enumerate() {
            match dir.join(d).canonicalize() {
                Ok(p) if p.is_dir() => allowed.push(p),
                Ok(_) => errors.push(field_error(format!("table_dirs[{k}]"), format!("`{d}` is not a directory"))),
                Err(e) => errors.push(field_error(
                    format!("table_dirs[{k}]"),
                    format!("cannot resolve `{d}` (relative to the config's directory): {e}"),
                )),
            }
        }
        allowed
    }
}

fn field_error(field: String, message: String) -> TableError {
    TableError::Field(FieldError { field, message })
}

/// Ok when `path`, resolved (`..` and links followed), lies in one of the `allowed`
/// directories: a table name cannot read an arbitrary file (`../../etc/shadow`, a link to
/// one) and echo its rows in an error. A path that does not resolve is left to the read,
/// whose error names it.
fn inside(path: &Path, allowed: &[PathBuf]) -> Result<(), String> {
    let Ok(resolved) = path.canonicalize() else { return Ok(()) };
    if allowed.iter().any(|d| resolved.starts_with(d)) {
        return Ok(());
    }
    Err(format!(
        "`{}` lies outside the config's directory{}: tables are read only from beside the config; move it there, or list its directory under `table_dirs`",
        resolved.display(),
        if allowed.len() > 1 { " and `table_dirs`" } else { "" }
    ))
}

/// Rows `t, f` of a CSV text (comma separated; blank lines skipped; the first row may be
/// a header), checked: two finite numbers a row, times strictly increasing, at least two
/// rows. Every bad row is reported at its line of `file`.
pub fn parse_table(text: &str, file: &str, field: &str) -> Result<Vec<[f64; 2]>, Vec<ValueError>> {
    let error = |line: Option<usize>, message: String| ValueError {
        file: file.to_string(),
        line,
        field: field.to_string(),
        message,
    };
    let mut errors = Vec::new();
    let mut points: Vec<[f64; 2]> = Vec::new();
    let mut last: Option<(f64, usize)> = None;
    let mut first_row = true;
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let row = raw.trim();
        if row.is_empty() {
            continue;
        }
        let cells: Vec<&str> = row.split(',').map(str::trim).collect();
        let numbers: Vec<Option<f64>> = cells.iter().map(|c| c.parse::<f64>().ok()).collect();
        let header = std::mem::take(&mut first_row) && numbers.iter().all(Option::is_none);
        if header {
            continue;
        }
        let (t, f) = match numbers[..] {
            [Some(t), Some(f)] => (t, f),
            _ => {
                errors.push(error(
                    Some(line),
                    format!(
                        "row `{}` is not two numbers; write each row as `time, value` (comma separated)",
                        excerpt(row)
                    ),
                ));
                continue;
            }
        };
        if !(t.is_finite() && f.is_finite()) {
            errors.push(error(
                Some(line),
                format!("row `{}` is not finite; every time and value must be a finite number", excerpt(row)),
            ));
            continue;
        }
        if let Some((before, at)) = last {
            if t <= before {
                errors.push(error(
                    Some(line),
                    format!(
                        "time {t} is not after {before} at line {at}; times must increase strictly: sort the rows and remove duplicates"
                    ),
                ));
            }
        }
        last = Some((t, line));
        points.push([t, f]);
    }
    if errors.is_empty() && points.len() < 2 {
        errors.push(error(
            None,
            format!(
                "has {} row(s) of data; a table needs at least 2 (`time, value` per line)",
                points.len()
            ),
        ));
    }
    if errors.is_empty() {
        Ok(points)
    } else {
        Err(errors)
    }
}

#[cfg(test)]
mod tests {
    use super::parse_table;

    /// A header, blank lines and spaces are allowed; the rows come out in order.
    #[test]
    fn reads_rows() {
        let points = parse_table("t, a\n0, 0\n\n0.5 , 1.5\n1,-2\n", "r.csv", "f").unwrap();
        assert_eq!(points, vec![[0.0, 0.0], [0.5, 1.5], [1.0, -2.0]]);
    }

    /// Each kind of bad row is reported at its line, all of them.
    #[test]
    fn reports_bad_rows_at_their_lines() {
        let errors = parse_table("0,0\n1;2\nnan,1\n0.5,1\n0.5,2\n", "r.csv", "f").unwrap_err();
        let lines: Vec<Option<usize>> = errors.iter().map(|e| e.line).collect();
        assert_eq!(lines, vec![Some(2), Some(3), Some(5)], "{errors:?}");
        assert!(errors[2].message.contains("not after 0.5 at line 4"), "{}", errors[2].message);
        let one = parse_table("time,value\n0,1\n", "r.csv", "f").unwrap_err();
        assert!(one[0].message.contains("at least 2"), "{}", one[0].message);
    }
}
