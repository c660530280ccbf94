//! Records the git revision the binary is built from (`tsim --version`): `git rev-parse
//! --short HEAD` with `-dirty` for uncommitted changes, "unknown" where there is no git or
//! no repository (a tarball, `cargo install` from a registry).

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    let text = String::from_utf8(out.stdout).ok()?;
    (out.status.success() && !text.trim().is_empty()).then(|| text.trim().to_string())
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let revision = git(&["rev-parse", "--short", "HEAD"]).map_or_else(
        || "unknown".to_string(),
        |rev| match git(&["status", "--porcelain", "--untracked-files=no"]) {
            Some(_) => format!("{rev}-dirty"),
            None => rev,
        },
    );
    // Rebuilt when HEAD moves (a commit, a checkout) or the index changes.
    for path in ["HEAD", "index"] {
        if let Some(p) = git(&["rev-parse", "--git-path", path]) {
            println!("cargo:rerun-if-changed={p}");
        }
    }
    if let Some(r) = git(&["symbolic-ref", "-q", "HEAD"]).and_then(|r| git(&["rev-parse", "--git-path", &r])) {
        println!("cargo:rerun-if-changed={r}");
    }
    println!("cargo:rustc-env=TSIM_GIT_REVISION={revision}");
}
