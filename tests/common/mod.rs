//! Helpers shared by the command-line tests: run the `pins` binary and check its outcome.
#![allow(dead_code)]

use std::process::{Command, Output};

/// Runs `pins` with `args`.
pub fn pins(args: &[&str]) -> Output {
    pins_with_threads(args, None)
}

/// Runs `pins` with `args`, optionally with `RAYON_NUM_THREADS` set.
pub fn pins_with_threads(args: &[&str], threads: Option<usize>) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_pins"));
    cmd.args(args);
    if let Some(t) = threads {
        cmd.env("RAYON_NUM_THREADS", t.to_string());
    }
    cmd.output().expect("run pins")
}

/// Asserts success; returns stdout.
pub fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "pins failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Asserts failure; returns stderr.
pub fn failed(out: &Output) -> String {
    assert!(
        !out.status.success(),
        "pins should fail: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}
