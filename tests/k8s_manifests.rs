//! `deploy/k8s`: the manifests parse as YAML, the Indexed Job is what the docs say (Indexed
//! completion mode, parallel pods, the shared results volume of the merge Job), and the command
//! lines the pods would run go through `evbench`'s own argument parser:
//!
//! - each pod's `sh -c` script runs for every `JOB_COMPLETION_INDEX` with `evbench` on `PATH`
//!   being a shim that calls the real binary with `--dry-run` added, in a copy of the image's
//!   working directory (the repository's `benchmark/configs` and `scenes`, as the Dockerfile
//!   copies them): every index gives a valid shard, and the shards cover each cell exactly once;
//! - the merge Job's script parses (a results folder that is not there is a run-time error, not
//!   a usage error: exit code 1 rather than clap's 2).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use evblur_tests::{temp_dir, workspace_binary};
use yaml_rust2::{Yaml, YamlLoader};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The single YAML document of `deploy/k8s/<name>`.
fn manifest(name: &str) -> Yaml {
    let path = repo().join("deploy/k8s").join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    let mut docs = YamlLoader::load_from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(docs.len(), 1, "{name}: one document");
    docs.remove(0)
}

/// The `sh -c` script of a Job's only container.
fn script(job: &Yaml) -> String {
    let containers = job["spec"]["template"]["spec"]["containers"].as_vec().unwrap();
    assert_eq!(containers.len(), 1);
    let c = &containers[0];
    let command: Vec<&str> = c["command"].as_vec().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    assert_eq!(command, ["/bin/sh", "-c"]);
    let args = c["args"].as_vec().unwrap();
    assert_eq!(args.len(), 1);
    args[0].as_str().unwrap().to_string()
}

/// The (volume name, claim, mount path) of a Job's results volume.
fn results_volume(job: &Yaml) -> (String, String, String) {
    let pod = &job["spec"]["template"]["spec"];
    let volume = &pod["volumes"][0];
    let mount = &pod["containers"][0]["volumeMounts"][0];
    assert_eq!(mount["name"].as_str(), volume["name"].as_str());
    (
        volume["name"].as_str().unwrap().into(),
        volume["persistentVolumeClaim"]["claimName"].as_str().unwrap().into(),
        mount["mountPath"].as_str().unwrap().into(),
    )
}

/// A folder laid out like the image's working directory, and a `bin/evbench` shim that runs the
/// real binary with `--dry-run` appended when the subcommand is `run`.
fn image_like_dir() -> (PathBuf, PathBuf) {
    let dir = temp_dir("k8s", "image");
    let work = dir.join("opt-evblur");
    evblur_tests::copy_dir(&repo().join("benchmark/configs"), &work.join("benchmark/configs"));
    evblur_tests::copy_dir(&repo().join("scenes"), &work.join("scenes"));
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let evbench = workspace_binary("evblur-benchmark", "evbench");
    let shim = format!(
        "#!/bin/sh\nif [ \"$1\" = run ]; then exec '{0}' \"$@\" --dry-run; fi\nexec '{0}' \"$@\"\n",
        evbench.display()
    );
    std::fs::write(bin.join("evbench"), shim).unwrap();
    Command::new("chmod").arg("+x").arg(bin.join("evbench")).status().unwrap();
    (work, bin)
}

fn run_script(script: &str, work: &Path, bin: &Path, index: Option<i64>) -> Output {
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let mut cmd = Command::new("/bin/sh");
    cmd.args(["-c", script]).current_dir(work).env("PATH", path).env_remove("RUST_BACKTRACE");
    if let Some(i) = index {
        cmd.env("JOB_COMPLETION_INDEX", i.to_string());
    }
    cmd.output().unwrap()
}

#[test]
fn the_indexed_job_runs_every_cell_once_and_the_merge_job_parses() {
    let job = manifest("evbench-job.yaml");
    assert_eq!(job["kind"].as_str(), Some("Job"));
    assert_eq!(job["apiVersion"].as_str(), Some("batch/v1"));
    let spec = &job["spec"];
    assert_eq!(spec["completionMode"].as_str(), Some("Indexed"));
    let n = spec["completions"].as_i64().unwrap();
    assert!(n >= 2 && spec["parallelism"].as_i64() == Some(n), "completions {n}, parallelism as many");
    let script = script(&job);
    assert!(script.contains("$((JOB_COMPLETION_INDEX+1))"), "{script}");
    let (_, claim, mount) = results_volume(&job);
    assert!(script.contains(&format!("--results {mount}/")), "results on the shared volume: {script}");

    let merge = manifest("merge-job.yaml");
    assert_eq!(merge["kind"].as_str(), Some("Job"));
    assert_eq!(results_volume(&merge).1, claim, "the merge Job mounts the shards' results");
    let pvc = manifest("results-pvc.yaml");
    assert_eq!(pvc["kind"].as_str(), Some("PersistentVolumeClaim"));
    assert_eq!(pvc["metadata"]["name"].as_str(), Some(claim.as_str()));
    assert_eq!(pvc["spec"]["accessModes"][0].as_str(), Some("ReadWriteMany"), "shards on several nodes write it");

    // The Dockerfile copies what the scripts use and makes it the working directory.
    let dockerfile = std::fs::read_to_string(repo().join("deploy/k8s/Dockerfile")).unwrap();
    for line in ["WORKDIR /opt/evblur", "COPY benchmark/configs/ benchmark/configs/", "COPY scenes/ scenes/"] {
        assert!(dockerfile.contains(line), "Dockerfile lacks {line:?}");
    }

    let (work, bin) = image_like_dir();
    let mut keys = BTreeSet::new();
    let mut total = None;
    for i in 0..n {
        let out = run_script(&script, &work, &bin, Some(i));
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "index {i}: {stdout}\n{}", String::from_utf8_lossy(&out.stderr));
        let header = stdout.lines().next().unwrap();
        println!("index {i}: {header}");
        assert!(header.contains(&format!("in shard {}/{n}", i + 1)), "index {i}: {header}");
        let cells: usize = header.split(": ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
        assert_eq!(*total.get_or_insert(cells), cells);
        // The cell lines: a 16-hex-digit key first.
        for line in stdout.lines().filter(|l| l.len() > 16 && l[..16].bytes().all(|b| b.is_ascii_hexdigit())) {
            assert!(keys.insert(line[..16].to_string()), "index {i}: cell {} in two shards", &line[..16]);
        }
    }
    assert_eq!(Some(keys.len()), total, "the {n} shards cover every cell of the matrix");

    let out = run_script(&self::script(&merge), &work, &bin, None);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("merge job without results: exit {:?}: {}", out.status.code(), stderr.trim());
    assert_eq!(out.status.code(), Some(1), "a run-time error about the missing results, not a usage error: {stderr}");
    assert!(stderr.contains("/results/table1") && !stderr.contains("Usage:"), "{stderr}");

    // The check can fail: a script with a flag evbench does not know is a usage error.
    let bad = script.replace("--quiet", "--quiett");
    let out = run_script(&bad, &work, &bin, Some(0));
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
}
