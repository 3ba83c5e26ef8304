//! `deploy/slurm` on a live one-node Slurm cluster: `tests/slurm/check.sh` (see its header)
//! installs slurm-wlm and munge when missing, starts private daemons on localhost, runs a small
//! variant of the quick matrix as a 2-task array plus the merge job and checks the merged table
//! against an unsharded run, then cancels one array task mid-cell, resubmits it and checks again.
//! It needs root; otherwise this test prints SKIPPED (the script's exit code 77).

use std::path::Path;
use std::process::Command;

use evblur_tests::{temp_dir, workspace_binary};

#[test]
fn slurm_array_and_merge_give_the_unsharded_table_even_after_a_cancelled_task() {
    let evbench = workspace_binary("evblur-benchmark", "evbench");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("slurm/check.sh");
    let work = temp_dir("slurm", "cluster");
    let out = Command::new("bash").arg(&script).arg(&evbench).arg(&work).output().unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    println!("{stdout}");
    if out.status.code() == Some(77) {
        println!("\n*** SKIPPED slurm test: {} ***\n", stdout.trim());
        return;
    }
    assert!(out.status.success(), "tests/slurm/check.sh failed:\n{stdout}\n{stderr}");
    assert!(stdout.contains("PASSED"), "{stdout}");
    std::fs::remove_dir_all(&work).ok();
}
