//! Bakes the source commit into the binary as `EVBLUR_GIT_COMMIT`: `git rev-parse HEAD` of the
//! workspace when it is built, with `-dirty` when the sources compiled into it (the three
//! crates, the embedded font, the workspace manifest, lock file and `.cargo/config.toml`)
//! differ from that commit, or `unknown` outside a git checkout (a source tarball) or without
//! git. Cells and tables record it, so a binary run after the checkout moved on still names
//! the code that trained. A build without `.git` (the container of `deploy/k8s`) can name it:
//! `EVBLUR_GIT_COMMIT=<commit> cargo build ...` (taken as given, without a dirty mark).
//!
//! Cargo runs this again when the commit can have changed (HEAD, the local branches) or
//! those sources changed (the dirty mark); not on index-only changes (`git add`), fetches, tags
//! or edits elsewhere (docs).

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    let crate_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let root = crate_dir.parent().expect("the benchmark crate sits in the workspace").to_path_buf();
    // What the binary is compiled from: the dirty mark looks at these only.
    let sources = [
        "simulator/src",
        "simulator/Cargo.toml",
        "trainer/src",
        "trainer/Cargo.toml",
        "benchmark/src",
        "benchmark/assets",
        "benchmark/Cargo.toml",
        "benchmark/build.rs",
        "Cargo.toml",
        "Cargo.lock",
        ".cargo/config.toml",
    ];
    for s in sources {
        rerun_if_exists(&root.join(s));
    }
    let git = |args: &[&str]| Command::new("git").arg("-C").arg(&root).args(args).output().ok();
    let text = |args: &[&str]| {
        git(args).filter(|o| o.status.success()).map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    // Only this workspace's own checkout counts (not a repository that happens to hold the
    // folder, such as the one around cargo's `target/package/` copy).
    let same = |a: &Path, b: &Path| a.canonicalize().ok().is_some_and(|a| b.canonicalize().ok() == Some(a));
    let own = text(&["rev-parse", "--show-toplevel"]).is_some_and(|top| same(Path::new(&top), &root));
    // The commit moves with HEAD (a checkout, a detached HEAD's commit) and with the local
    // branches (a commit, a reset: a loose ref, created when a packed one moves, or packed).
    if own {
        for dir_arg in ["--git-dir", "--git-common-dir"] {
            if let Some(dir) = text(&["rev-parse", dir_arg]) {
                let dir = root.join(dir);
                for name in ["HEAD", "packed-refs", "refs/heads"] {
                    rerun_if_exists(&dir.join(name));
                }
            }
        }
    }
    // A commit named by the builder wins (no dirty mark: there may be no tree to compare).
    println!("cargo:rerun-if-env-changed=EVBLUR_GIT_COMMIT");
    let given = std::env::var("EVBLUR_GIT_COMMIT").ok().map(|c| c.trim().to_string()).filter(|c| !c.is_empty());
    println!("cargo:rustc-env=EVBLUR_GIT_COMMIT_GIVEN={}", u8::from(given.is_some()));
    let head = if own { text(&["rev-parse", "HEAD"]) } else { None };
    let commit = match (given, head) {
        (Some(given), _) => given,
        (None, Some(head)) if !head.is_empty() => {
            let diff = [&["diff", "--quiet", "HEAD", "--"][..], &sources[..]].concat();
            let dirty = git(&diff).is_some_and(|o| o.status.code() == Some(1));
            if dirty {
                format!("{head}-dirty")
            } else {
                head
            }
        }
        _ => "unknown".to_string(),
    };
    println!("cargo:rustc-env=EVBLUR_GIT_COMMIT={commit}");
}

/// Asks cargo to run this script again when `path` (a file, or any file below a folder)
/// changes; paths that do not exist are left out (cargo would rerun on every build).
fn rerun_if_exists(path: &Path) {
    if path.exists() {
        println!("cargo:rerun-if-changed={}", path.display());
    }
}
