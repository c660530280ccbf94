//! The run directory's small files and their safety: atomic writes, the lock that keeps a
//! second `tsim run` out of a directory in use, and the check that a case's outputs are
//! still what its outcome recorded before a resume trusts them.

use crate::output::paraview::DIR as PARAVIEW_DIR;
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Writes `bytes` to `path` so that a reader sees the old file or the whole new one, never
/// a part, and the new one survives a crash once this returns: a temporary file beside it,
/// flushed to disk, renamed over it, and the directory entry flushed.
/// A failure names `path` (a full disk otherwise reads "No space left on device" of no
/// file), and leaves no temporary file behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    // A fresh file, never through a link planted at the temporary name: O_EXCL does not
    // follow links, and a leftover of a killed run is removed first (the entry, not what
    // it may point to).
    let _ = std::fs::remove_file(&tmp);
    let write = || {
        let mut file = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&tmp, path)
    };
    if let Err(e) = write() {
        let _ = std::fs::remove_file(&tmp);
        return Err(std::io::Error::new(e.kind(), format!("{}: {e}", path.display())));
    }
    std::fs::File::open(dir)?.sync_all()
}

/// Writes the run's copy of every table `cases` read from a file (`tables/<name>`, named
/// by their `case.yaml`), unless it is there with the same content.
pub fn keep_tables(dir: &Path, cases: &[&crate::run::Case]) -> std::io::Result<()> {
    let mut kept: BTreeMap<std::sync::Arc<str>, crate::config::TablePoints> = BTreeMap::new();
    for case in cases {
        kept.extend(case.config.kept_tables());
    }
    if kept.is_empty() {
        return Ok(());
    }
    let tables = dir.join(crate::config::KEPT_TABLES);
    std::fs::create_dir_all(&tables).map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", tables.display())))?;
    for (name, points) in kept {
        let text = crate::config::table_csv(&points);
        let path = tables.join(&*name);
        if std::fs::read(&path).ok().as_deref() != Some(text.as_bytes()) {
            write_atomic(&path, text.as_bytes())?;
        }
    }
    Ok(())
}

/// The files a case writes in its directory (and its ParaView files in [`PARAVIEW_DIR`]).
const CASE_FILES: [&str; 4] = ["case.yaml", "result.h5", "replay.mcap", "outcome.json"];

/// Makes `dir` safe to write a case into: Err when the directory is a symbolic link (its
/// files would land wherever it points, outside --out); a link standing in place of one
/// of the case's files or of its ParaView directory is removed (the link, never its
/// target), so that the file is created afresh inside the directory rather than written
/// through the link. A ParaView directory of an earlier run is removed whole: its stages
/// may not be this run's.
pub fn unlink_planted(dir: &Path) -> Result<(), String> {
    let is_link = |p: &Path| p.symlink_metadata().is_ok_and(|m| m.file_type().is_symlink());
    if is_link(dir) {
        return Err(format!(
            "{} is a symbolic link: a case writes only inside its run directory; remove the link",
            dir.display()
        ));
    }
    for name in CASE_FILES.into_iter().chain([PARAVIEW_DIR]) {
        let path = dir.join(name);
        if is_link(&path) {
            std::fs::remove_file(&path).map_err(|e| format!("cannot remove the link {}: {e}", path.display()))?;
        }
    }
    let paraview = dir.join(PARAVIEW_DIR);
    if paraview.is_dir() {
        std::fs::remove_dir_all(&paraview).map_err(|e| format!("cannot remove {}: {e}", paraview.display()))?;
    }
    Ok(())
}

/// An output file of a complete case, as its outcome records it.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct OutputFile {
    /// [bytes]
    pub bytes: u64,
    /// CRC-32 of the whole file (IEEE, as gzip and zlib compute it), 8 hex digits.
    pub crc32: String,
}

/// The output files of a case by name.
pub type OutputFiles = BTreeMap<String, OutputFile>;

/// First bytes of an HDF5 file, and the last bytes of a finished MCAP file (its footer's
/// closing magic).
const HDF5_SIGNATURE: &[u8] = b"\x89HDF\r\n\x1a\n";
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// A file read through once: its length, CRC-32 and the bytes its format's signature is
/// checked in (the first and the last 8).
struct Scan {
    bytes: u64,
    crc32: u32,
    head: Vec<u8>,
    tail: Vec<u8>,
}

/// Reads `path` in 1 MiB blocks (a result.h5 may be many GB; it is not held whole).
fn scan(path: &Path) -> std::io::Result<Scan> {
    let mut file = std::fs::File::open(path)?;
    let mut block = vec![0u8; 1 << 20];
    let mut out = Scan {
        bytes: 0,
        crc32: 0,
        head: Vec::new(),
        tail: Vec::new(),
    };
    loop {
        let n = match file.read(&mut block) {
            Ok(0) => return Ok(out),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        let read = &block[..n];
        out.crc32 = zlib_rs::crc32::crc32(out.crc32, read);
        out.bytes += n as u64;
        if out.head.len() < 8 {
            out.head.extend(read.iter().take(8 - out.head.len()));
        }
        out.tail.extend_from_slice(&read[n.saturating_sub(8)..]);
        let excess = out.tail.len().saturating_sub(8);
        out.tail.drain(..excess);
    }
}

/// The output files a finished case wrote, with their lengths and checksums: result.h5,
/// replay.mcap and `paraview/<stage>.vtkhdf`, each under its name in `dir`.
pub fn output_files(dir: &Path) -> OutputFiles {
    let mut paraview: Vec<String> = std::fs::read_dir(dir.join(PARAVIEW_DIR))
        .into_iter()
        .flatten()
        .filter_map(|entry| entry.ok()?.file_name().into_string().ok())
        .filter(|name| name.ends_with(".vtkhdf"))
        .map(|name| format!("{PARAVIEW_DIR}/{name}"))
        .collect();
    paraview.sort();
    ["result.h5".to_string(), "replay.mcap".to_string()]
        .into_iter()
        .chain(paraview)
        .filter_map(|name| {
            let s = scan(&dir.join(&name)).ok()?;
            Some((
                name,
                OutputFile {
                    bytes: s.bytes,
                    crc32: format!("{:08x}", s.crc32),
                },
            ))
        })
        .collect()
}

/// Why the outputs in `dir` are not the ones recorded in `files`, if they are not: a file
/// missing, of another length, without its format's signature (HDF5 header, MCAP closing
/// magic), or with other contents (its CRC-32: a byte changed anywhere).
pub fn changed(dir: &Path, files: &OutputFiles) -> Option<String> {
    for (name, recorded) in files {
        let s = match scan(&dir.join(name)) {
            Ok(s) => s,
            Err(e) => return Some(format!("{name}: {e}")),
        };
        if s.bytes != recorded.bytes {
            return Some(format!("{name} is {} bytes, {} when the case completed", s.bytes, recorded.bytes));
        }
        let intact = match name.as_str() {
            "replay.mcap" => s.tail.ends_with(MCAP_MAGIC),
            // result.h5 and the ParaView files.
            _ => s.head.starts_with(HDF5_SIGNATURE),
        };
        if !intact {
            return Some(format!("{name} lacks its format's signature"));
        }
        if format!("{:08x}", s.crc32) != recorded.crc32 {
            return Some(format!(
                "{name}'s contents changed since the case completed (CRC-32 {:08x}, recorded {})",
                s.crc32, recorded.crc32
            ));
        }
    }
    None
}

/// A run directory held by this process: `.lock` (a whole run) or `.lock.shard-I-of-N`
/// (one shard of it) names the host, the process and the Slurm job; dropped, it is
/// removed. A second `tsim run` into the same directory stops with an error instead of
/// writing the same files (which corrupted them, or hung on HDF5's file locks); shards of
/// one partition share the directory, since their cases differ, but not with a whole run
/// nor with shards of another partition. `tsim collect` takes the whole directory too, as
/// a reader: a run that finds it there waits for it (at most [`READER_WAIT`]) rather than
/// failing, since collect holds it for as long as it takes to read the files. A lock whose holder is gone is stale and taken
/// over: on this host its process has ended; from another host, its Slurm job has left
/// the queue (`squeue`); a lock from another host without a Slurm job stays (two runs
/// that find the same stale lock at the same instant could both take it over; that needs
/// a crashed run and two new ones started within microseconds).
pub struct RunLock {
    path: PathBuf,
}

pub fn host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| std::fs::read_to_string("/etc/hostname"))
        .map(|h| h.trim().to_string())
        .unwrap_or_else(|_| "unknown".into())
}

const WHOLE: &str = ".lock";
const SHARD: &str = ".lock.shard-";
/// The word a reader's lock ends with (after host, process and Slurm job).
const READER: &str = "collect";
/// Longest wait of a run for a reader to release the directory: `tsim collect` of the
/// 27-case sweep reads its files in under a second.
pub const READER_WAIT: std::time::Duration = std::time::Duration::from_secs(60);
const READER_POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// Who takes a run directory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Holder {
    /// `tsim run` (or a shard of it): writes the cases.
    Run,
    /// `tsim collect`: reads them and writes the summaries.
    Collect,
}

/// Who holds the lock file at `path`, if it is held: its text ("host pid [slurm job]").
/// A stale lock is removed.
fn holder(path: &Path) -> std::io::Result<Option<String>> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(None);
    };
    let mut parts = text.split_whitespace();
    let (lock_host, pid, job) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""), parts.next());
    let alive = if lock_host == host() && !pid.is_empty() {
        Path::new("/proc").join(pid).exists()
    } else {
        job.is_none_or(slurm_job_queued)
    };
    if alive {
        return Ok(Some(text));
    }
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e),
        _ => Ok(None),
    }
}

/// Whether Slurm still lists job `id` as pending or running; true when `squeue` cannot
/// tell (not installed, controller down): a lock is kept when in doubt.
fn slurm_job_queued(id: &str) -> bool {
    match std::process::Command::new("squeue").args(["-h", "-o", "%T", "-j", id]).output() {
        Ok(out) if out.status.success() => {
            let states = String::from_utf8_lossy(&out.stdout);
            states.split_whitespace().any(|s| {
                !matches!(
                    s,
                    "COMPLETED"
                        | "FAILED"
                        | "CANCELLED"
                        | "TIMEOUT"
                        | "NODE_FAIL"
                        | "OUT_OF_MEMORY"
                        | "PREEMPTED"
                        | "BOOT_FAIL"
                        | "DEADLINE"
                )
            })
        }
        // An id the controller no longer knows exits 1 with "Invalid job id".
        Ok(out) => !String::from_utf8_lossy(&out.stderr).contains("Invalid job id"),
        Err(_) => true,
    }
}

fn in_use(dir: &Path, holder: &str) -> std::io::Error {
    let mut parts = holder.split_whitespace();
    let (host, pid) = (parts.next().unwrap_or("?"), parts.next().unwrap_or("?"));
    let rest: Vec<&str> = parts.collect();
    let command = if rest.last() == Some(&READER) { "tsim collect" } else { "tsim run" };
    let job = rest
        .iter()
        .find(|w| **w != READER)
        .map_or_else(String::new, |j| format!(", Slurm job {j}"));
    std::io::Error::new(
        std::io::ErrorKind::WouldBlock,
        format!(
            "{} is in use by `{command}` (process {pid} on host {host}{job}); wait for it, or remove its .lock* file if that process is gone",
            dir.display()
        ),
    )
}

/// Whether the lock file at `path` is a reader's.
fn held_by_reader(path: &Path) -> bool {
    std::fs::read_to_string(path).is_ok_and(|t| t.split_whitespace().last() == Some(READER))
}

impl RunLock {
    /// The whole run directory: refused while another run or any shard holds it; a run
    /// waits for a reader (`tsim collect`) to finish, at most [`READER_WAIT`].
    pub fn acquire(dir: &Path, who: Holder) -> std::io::Result<RunLock> {
        let lock = Self::take(dir, WHOLE, who)?;
        match Self::shard_holders(dir)?.into_iter().next() {
            Some((_, holder)) => Err(in_use(dir, &holder)),
            None => Ok(lock),
        }
    }

    /// Shard `index` of `count`: refused while the whole run, the same shard, or a shard
    /// of another count holds the directory.
    pub fn shard(dir: &Path, index: usize, count: usize) -> std::io::Result<RunLock> {
        let lock = Self::take(dir, &format!("{SHARD}{index}-of-{count}"), Holder::Run)?;
        // A reader of the whole directory (the merge) is waited for as by a whole run.
        Self::wait_for_reader(dir);
        if let Some(holder) = holder(&dir.join(WHOLE))? {
            return Err(in_use(dir, &holder));
        }
        let suffix = format!("-of-{count}");
        match Self::shard_holders(dir)?.into_iter().find(|(name, _)| !name.ends_with(&suffix)) {
            Some((_, holder)) => Err(in_use(dir, &holder)),
            None => Ok(lock),
        }
    }

    /// The live shard locks in `dir`: (file name, holder).
    fn shard_holders(dir: &Path) -> std::io::Result<Vec<(String, String)>> {
        let mut held = Vec::new();
        for entry in std::fs::read_dir(dir)? {
            let name = entry?.file_name().to_string_lossy().into_owned();
            if name.starts_with(SHARD) {
                if let Some(h) = holder(&dir.join(&name))? {
                    held.push((name, h));
                }
            }
        }
        Ok(held)
    }

    /// Waits while a reader holds the whole directory, at most [`READER_WAIT`].
    fn wait_for_reader(dir: &Path) {
        let started = std::time::Instant::now();
        while held_by_reader(&dir.join(WHOLE)) && started.elapsed() < READER_WAIT {
            std::thread::sleep(READER_POLL);
        }
    }

    /// Takes the lock file `name` in `dir` for `who`, or says who holds it; a run waits
    /// for a reader holding it, at most [`READER_WAIT`].
    fn take(dir: &Path, name: &str, who: Holder) -> std::io::Result<RunLock> {
        let path = dir.join(name);
        let job = std::env::var("SLURM_JOB_ID").map_or_else(|_| String::new(), |j| format!(" {j}"));
        let reader = if who == Holder::Collect {
            format!(" {READER}")
        } else {
            String::new()
        };
        let me = format!("{} {}{job}{reader}", host(), std::process::id());
        // The lock appears whole or not at all: written to a file of this process, then
        // hard-linked to its name, which fails if that exists (atomic, even on NFS). A
        // lock created empty and filled afterwards was read as stale by a second run
        // started at the same moment, and both ran.
        // (Its name is no lock's: other shards list the locks while it exists.)
        let mine = dir.join(format!(".taking-{}{name}", std::process::id()));
        write_atomic(&mine, me.as_bytes())?;
        let started = std::time::Instant::now();
        let mut stale_taken_over = false;
        let taken = loop {
            match std::fs::hard_link(&mine, &path) {
                Ok(()) => break Ok(RunLock { path: path.clone() }),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => match holder(&path) {
                    Err(e) => break Err(e),
                    Ok(Some(_)) if who == Holder::Run && held_by_reader(&path) && started.elapsed() < READER_WAIT => {
                        std::thread::sleep(READER_POLL)
                    }
                    Ok(Some(holder)) => break Err(in_use(dir, &holder)),
                    // Stale, and removed: try again, once.
                    Ok(None) if !stale_taken_over => stale_taken_over = true,
                    Ok(None) => break Err(std::io::Error::other(format!("cannot take {}", path.display()))),
                },
                Err(e) => break Err(e),
            }
        };
        let _ = std::fs::remove_file(&mine);
        taken
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh directory for one test, removed when dropped.
    fn scratch(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new().prefix(&format!("tsim-files-{name}-")).tempdir().unwrap()
    }

    #[test]
    fn a_second_lock_is_refused_and_a_stale_one_taken_over() {
        let scratch_dir = scratch("lock");
        let dir = scratch_dir.path();
        let first = RunLock::acquire(dir, Holder::Run).unwrap();
        let err = RunLock::acquire(dir, Holder::Run)
            .err()
            .expect("a second lock while the first is held");
        assert!(err.to_string().contains("in use"), "{err}");
        assert!(RunLock::shard(dir, 0, 2).is_err(), "no shard while the whole run is held");
        drop(first);
        assert!(!dir.join(".lock").exists());
        // A lock of a process that is gone (pid 0 is never a user process) is stale.
        std::fs::write(dir.join(".lock"), format!("{} 0", host())).unwrap();
        let _taken = RunLock::acquire(dir, Holder::Run).unwrap();
    }

    /// A run that finds `tsim collect` reading the directory waits for it and then runs
    /// (it failed: a run racing collect exited 1 in the campaign); collect finding a run is
    /// refused, naming the run, and a second collect is refused naming the collect.
    #[test]
    fn a_run_waits_for_a_reader_and_a_reader_is_refused_by_a_run() {
        let scratch_dir = scratch("reader");
        let dir = scratch_dir.path().to_path_buf();
        let reading = RunLock::acquire(&dir, Holder::Collect).unwrap();
        let err = RunLock::acquire(&dir, Holder::Collect).err().expect("two readers at once");
        assert!(err.to_string().contains("in use by `tsim collect`"), "{err}");
        let released = std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(300));
            drop(reading);
        });
        let started = std::time::Instant::now();
        let run = RunLock::acquire(&dir, Holder::Run).unwrap();
        assert!(
            started.elapsed() >= std::time::Duration::from_millis(250),
            "{:?}",
            started.elapsed()
        );
        released.join().unwrap();
        let err = RunLock::acquire(&dir, Holder::Collect).err().expect("collect while a run holds it");
        assert!(err.to_string().contains("in use by `tsim run`"), "{err}");
        drop(run);
    }

    #[test]
    fn shards_of_one_partition_share_a_directory() {
        let scratch_dir = scratch("shards");
        let dir = scratch_dir.path();
        let first = RunLock::shard(dir, 0, 3).unwrap();
        let second = RunLock::shard(dir, 1, 3).unwrap();
        assert!(RunLock::shard(dir, 1, 3).is_err(), "the same shard twice");
        assert!(RunLock::shard(dir, 0, 2).is_err(), "a shard of another partition");
        let err = RunLock::acquire(dir, Holder::Run).err().expect("no whole run while shards run");
        assert!(err.to_string().contains("in use"), "{err}");
        assert!(!dir.join(WHOLE).exists(), "the refused whole run left no lock");
        drop((first, second));
        let _whole = RunLock::acquire(dir, Holder::Run).unwrap();
    }

    #[test]
    fn changed_outputs_are_found() {
        let scratch_dir = scratch("verify");
        let dir = scratch_dir.path();
        let mut h5 = HDF5_SIGNATURE.to_vec();
        h5.extend([0u8; 100]);
        let mut mcap = vec![1u8; 50];
        mcap.extend(MCAP_MAGIC);
        std::fs::write(dir.join("result.h5"), &h5).unwrap();
        std::fs::write(dir.join("replay.mcap"), &mcap).unwrap();
        let files = output_files(dir);
        assert_eq!(files.len(), 2);
        assert_eq!(changed(dir, &files), None);
        std::fs::write(dir.join("result.h5"), &h5[..50]).unwrap();
        assert!(changed(dir, &files).unwrap().contains("result.h5 is 50 bytes"));
        // One byte flipped in the middle, length and signature intact.
        let mut flipped = h5.clone();
        flipped[50] ^= 0x10;
        std::fs::write(dir.join("result.h5"), &flipped).unwrap();
        assert!(changed(dir, &files).unwrap().contains("result.h5's contents changed"));
        std::fs::write(dir.join("result.h5"), &h5).unwrap();
        std::fs::write(dir.join("replay.mcap"), vec![0u8; mcap.len()]).unwrap();
        assert!(changed(dir, &files).unwrap().contains("signature"));
        std::fs::remove_file(dir.join("replay.mcap")).unwrap();
        assert!(changed(dir, &files).unwrap().starts_with("replay.mcap"));
    }

    /// The ParaView files count among a case's outputs, checked as HDF5 files; a run's
    /// start removes an earlier run's directory of them (its stages may not be this run's),
    /// and a link planted in its place (the link, not its target).
    #[test]
    fn paraview_files_are_outputs_and_an_old_run_s_are_removed() {
        let scratch_dir = scratch("paraview");
        let dir = scratch_dir.path();
        let paraview = dir.join(PARAVIEW_DIR);
        std::fs::create_dir(&paraview).unwrap();
        let mut h5 = HDF5_SIGNATURE.to_vec();
        h5.extend([0u8; 100]);
        std::fs::write(paraview.join("drop.vtkhdf"), &h5).unwrap();
        std::fs::write(paraview.join("notes.txt"), b"not an output").unwrap();
        let files = output_files(dir);
        assert_eq!(files.keys().collect::<Vec<_>>(), ["paraview/drop.vtkhdf"]);
        assert_eq!(changed(dir, &files), None);
        std::fs::write(paraview.join("drop.vtkhdf"), vec![0u8; h5.len()]).unwrap();
        assert!(changed(dir, &files)
            .unwrap()
            .contains("paraview/drop.vtkhdf lacks its format's signature"));
        unlink_planted(dir).unwrap();
        assert!(!paraview.exists());
        let elsewhere = scratch("paraview_target");
        std::os::unix::fs::symlink(elsewhere.path(), &paraview).unwrap();
        unlink_planted(dir).unwrap();
        assert!(!paraview.exists() && elsewhere.path().exists());
    }

    #[test]
    fn atomic_write_replaces_whole() {
        let scratch_dir = scratch("atomic");
        let dir = scratch_dir.path();
        let path = dir.join("outcome.json");
        write_atomic(&path, b"first").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert_eq!(std::fs::read_dir(dir).unwrap().count(), 1, "no temporary file left");
    }

    /// A write that fails (here the rename: a non-empty directory stands at the path; on
    /// a full disk, the write) names the path and leaves no temporary file (issue 29:
    /// ".outcome.json.<pid>.tmp" stayed behind, the error named no file).
    #[test]
    fn a_failed_atomic_write_names_the_path_and_cleans_up() {
        let scratch_dir = scratch("atomic-fail");
        let dir = scratch_dir.path();
        let path = dir.join("outcome.json");
        std::fs::create_dir_all(path.join("occupied")).unwrap();
        let e = write_atomic(&path, b"lost").unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: ", path.display())), "{e}");
        let names: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["outcome.json"], "a temporary file left");
    }
}
