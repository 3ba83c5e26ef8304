//! The bad-input corpus: a few hundred malformed inputs, generated below from valid ones, each
//! run through the command a user would type (`evsim render / dataset / check / events`,
//! `evtrain train / eval`, `evbench run`). Every case must end in a *clean error*: a non-zero
//! exit (not a panic's 101, not a signal), no "panicked" in the output, and a message that names
//! the file (and, where the case says so, the field). The families:
//!
//! - `gltf`: a small textured, lit glTF scene (and its `.glb` form) with an index out of range,
//!   a required field removed, an out-of-spec value, or a truncated / missing / corrupt file;
//! - `obj`: an OBJ + MTL scene with bad faces, numbers, materials and textures;
//! - `scene-toml`: the `.toml` scene description with every leaf given a wrong type or NaN, an
//!   unknown key in every table, and out-of-range values;
//! - `dataset`: a simulated dataset with a file deleted, truncated or replaced by an
//!   inconsistent one, each case run through both `evsim check` and `evtrain train`;
//! - `checkpoint`: a trained run whose `checkpoint.bin` or `config.toml` is truncated, flipped
//!   or deleted, through `evtrain eval` and `evtrain train --resume`;
//! - `train-set`: `evtrain train --set` with wrong types, NaN and impossible sizes;
//! - `matrix`: `evbench run --dry-run` on broken run-matrix files;
//! - `events`: `evsim events` on broken frame folders, timestamp files and settings.
//!
//! Each family first runs its valid base and requires it to succeed, so a case fails because
//! of its mutation. The test prints one line per family and a total, and fails listing every
//! case that panicked, aborted, succeeded, or gave an error that does not name the file.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use evblur_tests::{copy_dir, temp_dir, workspace_binary};
use rayon::prelude::*;
use serde_json::{json, Value};

/// One bad input: the command to run and the words its error must contain.
struct Case {
    family: &'static str,
    name: String,
    exe: &'static Path,
    args: Vec<OsString>,
    /// Every one of these must appear in the error output (file names, field names).
    must_name: Vec<String>,
}

/// How a case ended.
#[derive(Debug, PartialEq)]
enum Outcome {
    Clean,
    SilentSuccess,
    Panic,
    Abort(String),
    Unclear(Vec<String>),
}

fn evsim() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| workspace_binary("evblur-simulator", "evsim"))
}

fn evtrain() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| workspace_binary("evblur-trainer", "evtrain"))
}

fn evbench() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| workspace_binary("evblur-benchmark", "evbench"))
}

fn root() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| temp_dir("bad", "inputs"))
}

/// A fresh folder for one case (or base) of a family.
fn case_dir(family: &str, name: &str) -> PathBuf {
    let safe: String = name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
    let dir = root().join(family).join(safe);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn os(args: &[&str]) -> Vec<OsString> {
    args.iter().map(OsString::from).collect()
}

fn p(path: &Path) -> OsString {
    path.as_os_str().to_owned()
}

/// Runs a command: (exit code or None for a signal, stdout + stderr).
fn run(exe: &Path, args: &[OsString]) -> (Option<i32>, String) {
    let out =
        Command::new(exe).args(args).env_remove("RUST_BACKTRACE").env_remove("RUST_LIB_BACKTRACE").output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    (out.status.code(), text)
}

/// Runs a valid base command and fails the test unless it succeeds.
fn run_ok(exe: &Path, args: &[OsString]) {
    let (code, text) = run(exe, args);
    assert_eq!(code, Some(0), "base case {} {args:?} failed:\n{text}", exe.display());
}

fn classify(case: &Case) -> (Outcome, String) {
    let (code, text) = run(case.exe, &case.args);
    let outcome = match code {
        None => Outcome::Abort("killed by a signal".into()),
        _ if text.contains("panicked") => Outcome::Panic,
        Some(101) => Outcome::Panic,
        Some(0) => Outcome::SilentSuccess,
        Some(_) => {
            let missing: Vec<String> = case.must_name.iter().filter(|w| !text.contains(w.as_str())).cloned().collect();
            if missing.is_empty() {
                Outcome::Clean
            } else {
                Outcome::Unclear(missing)
            }
        }
    };
    (outcome, text)
}

#[path = "bad_inputs/scenes.rs"]
mod scenes;
use scenes::*;
#[path = "bad_inputs/runs.rs"]
mod runs;
use runs::*;

#[test]
fn every_bad_input_of_the_corpus_ends_in_a_clean_error() {
    let families: [(&str, Family); 8] = [
        ("gltf", gltf_cases),
        ("obj", obj_cases),
        ("scene-toml", scene_toml_cases),
        ("dataset", dataset_cases),
        ("checkpoint", checkpoint_cases),
        ("train-set", train_set_cases),
        ("matrix", matrix_cases),
        ("events", events_cases),
    ];
    let mut failures = Vec::new();
    let mut total = 0;
    for (family, make) in families {
        let cases = make();
        let results: Vec<(String, Outcome, String)> = cases
            .par_iter()
            .map(|c| {
                let start = std::time::Instant::now();
                let (o, text) = classify(c);
                let secs = start.elapsed().as_secs_f64();
                if secs > 5.0 {
                    println!("  slow case [{}] {}: {secs:.1} s", c.family, c.name);
                }
                (c.name.clone(), o, text)
            })
            .collect();
        let count = |f: &dyn Fn(&Outcome) -> bool| results.iter().filter(|r| f(&r.1)).count();
        println!(
            "{family:<11} {:>4} cases: {:>4} clean, {} panics, {} aborts, {} silent successes, {} unclear messages",
            results.len(),
            count(&|o| *o == Outcome::Clean),
            count(&|o| *o == Outcome::Panic),
            count(&|o| matches!(o, Outcome::Abort(_))),
            count(&|o| *o == Outcome::SilentSuccess),
            count(&|o| matches!(o, Outcome::Unclear(_))),
        );
        total += results.len();
        for (name, outcome, text) in results {
            if outcome != Outcome::Clean {
                let tail: String =
                    text.lines().rev().take(6).collect::<Vec<_>>().into_iter().rev().collect::<Vec<_>>().join("\n    ");
                let line = format!("[{family}] {name}: {outcome:?}\n    {tail}");
                println!("{line}");
                failures.push(line);
            }
        }
    }
    println!("bad-input corpus: {total} cases, {} not clean", failures.len());
    assert!(total >= 300, "the corpus shrank to {total} cases");
    assert!(
        failures.is_empty(),
        "{} of {total} bad inputs did not end in a clean error:\n{}",
        failures.len(),
        failures.join("\n")
    );
    let _ = std::fs::remove_dir_all(root());
}
