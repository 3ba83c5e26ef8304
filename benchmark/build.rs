//! Bakes the source commit into the binary as `EVBLUR_GIT_COMMIT`: `git rev-parse HEAD` of the
//! workspace when it is built, with `-dirty` when the sources compiled into it (the three
//! crates, the workspace manifest and lock file) differ from that commit, or `unknown` outside
//! a git checkout (a source tarball) or without git. Cells and tables record it, so a binary
//! run after the checkout moved on still names the code that trained. A build without `.git`
//! (the container of `deploy/k8s`) can name it: `EVBLUR_GIT_COMMIT=<commit> cargo build ...`.
//!
//! Cargo runs this again when the commit can have changed (HEAD, the refs) or those sources
//! changed (the dirty mark); not on index-only changes (`git add`) or edits elsewhere (docs).

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
        "benchmark/Cargo.toml",
        "benchmark/build.rs",
        "Cargo.toml",
        "Cargo.lock",
    ];
    for s in sources {
        rerun_if_exists(&root.join(s));
    }
    let git = |args: &[&str]| Command::new("git").arg("-C").arg(&root).args(args).output().ok();
    let text = |args: &[&str]| {
        git(args).filter(|o| o.status.success()).map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    // The commit moves with HEAD (a checkout) and with the refs (a commit, a fetch, a reset).
    for dir_arg in ["--git-dir", "--git-common-dir"] {
        if let Some(dir) = text(&["rev-parse", dir_arg]) {
            let dir = root.join(dir);
            for name in ["HEAD", "refs", "packed-refs"] {
                rerun_if_exists(&dir.join(name));
            }
        }
    }
    // A commit named by the builder wins (no dirty mark: there may be no tree to compare).
    println!("cargo:rerun-if-env-changed=EVBLUR_GIT_COMMIT");
    let given = std::env::var("EVBLUR_GIT_COMMIT").ok().map(|c| c.trim().to_string()).filter(|c| !c.is_empty());
    println!("cargo:rustc-env=EVBLUR_GIT_COMMIT_GIVEN={}", u8::from(given.is_some()));
    let commit = match (given, text(&["rev-parse", "HEAD"])) {
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
