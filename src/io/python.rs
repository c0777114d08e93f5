//! Running a Python script compiled into the binary: piped to `python -` with its arguments,
//! so no script file needs to exist beside the binary (the OpenCV peers of the benchmarks and
//! the tracking experiments run this way).

use std::ffi::OsStr;
use std::io::Write;
use std::process::{Command, Output, Stdio};

use crate::error::{Error, Result};

/// Runs `script` (named `name` in messages) under `python` with `args`; its output when it
/// succeeds, else an error under `field` with the script's last words on stderr.
pub fn run_piped<I, S>(
    python: &str,
    script: &str,
    name: &str,
    field: &str,
    args: I,
) -> Result<Output>
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let mut child = Command::new(python)
        .arg("-")
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| Error::invalid(field, format!("{python} could not be started: {e}")))?;
    if let Some(mut stdin) = child.stdin.take() {
        stdin
            .write_all(script.as_bytes())
            .map_err(|e| Error::invalid(field, format!("piping {name} to {python}: {e}")))?;
    }
    let out = child
        .wait_with_output()
        .map_err(|e| Error::invalid(field, format!("waiting for {python}: {e}")))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(Error::invalid(
            field,
            format!("{name} failed ({}): {}", out.status, err.trim()),
        ));
    }
    Ok(out)
}
