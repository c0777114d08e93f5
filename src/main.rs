//! The `pins` command line: parses flags, calls the library, prints. No logic of its own.

fn main() -> anyhow::Result<()> {
    Ok(())
}
