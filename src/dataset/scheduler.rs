//! The shard of a `pins generate` run from a cluster scheduler's environment: Slurm job arrays
//! (`SLURM_ARRAY_TASK_ID`, `_MIN`, `_MAX`, `_STEP`, `_COUNT`) and Kubernetes Indexed Jobs
//! (`JOB_COMPLETION_INDEX`, with the shard count from `--shards` or `PINS_SHARD_COUNT`, which
//! Kubernetes does not export). An explicit `--shard K/N` always wins.

use super::generate::Shard;
use crate::error::{Error, Result};

/// Where a run's shard came from, for the message that says so.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ShardSource {
    pub shard: Shard,
    /// e.g. `--shard 2/4`, `Slurm job array (SLURM_ARRAY_TASK_ID=3, …)`, or `no scheduler`.
    pub origin: String,
}

/// Decides the shard: `--shard` if given, else Slurm's array variables, else Kubernetes'
/// completion index, else the whole dataset. `shards` is `--shards N`; `var` reads the
/// environment (a closure so tests need not touch the process's own).
pub fn resolve(
    flag: Option<&str>,
    shards: Option<usize>,
    var: impl Fn(&str) -> Option<String>,
) -> Result<ShardSource> {
    let count_env = read_usize(&var, "PINS_SHARD_COUNT")?;
    if let (Some(a), Some(b)) = (shards, count_env)
        && a != b
    {
        return Err(Error::invalid(
            "--shards",
            format!("--shards {a} disagrees with PINS_SHARD_COUNT={b}"),
        ));
    }
    let count = shards.or(count_env);
    if let Some(s) = flag {
        let shard = Shard::parse(s)?;
        if let Some(n) = count
            && n != shard.count
        {
            return Err(Error::invalid(
                "--shard",
                format!(
                    "--shard {s} has {} shards, --shards/PINS_SHARD_COUNT says {n}",
                    shard.count
                ),
            ));
        }
        return Ok(ShardSource {
            shard,
            origin: format!("--shard {s}"),
        });
    }
    if let Some(id) = read_i64(&var, "SLURM_ARRAY_TASK_ID")? {
        return slurm(id, count, &var);
    }
    if let Some(index) = read_usize(&var, "JOB_COMPLETION_INDEX")? {
        let Some(n) = count else {
            return Err(Error::invalid(
                "--shards",
                format!(
                    "JOB_COMPLETION_INDEX={index} (a Kubernetes Indexed Job) needs the shard \
                     count: pass --shards N (the Job's completions) or set PINS_SHARD_COUNT"
                ),
            ));
        };
        if n == 0 || index >= n {
            return Err(Error::invalid(
                "JOB_COMPLETION_INDEX",
                format!("index {index} is not below the shard count {n}"),
            ));
        }
        return Ok(ShardSource {
            shard: Shard { index, count: n },
            origin: format!("Kubernetes Indexed Job (JOB_COMPLETION_INDEX={index}, {n} shards)"),
        });
    }
    if let Some(n) = count
        && n != 1
    {
        return Err(Error::invalid(
            "--shards",
            format!(
                "{n} shards but no shard index: pass --shard K/{n}, or run under a Slurm array \
                 or a Kubernetes Indexed Job"
            ),
        ));
    }
    Ok(ShardSource {
        shard: Shard::ALL,
        origin: "no scheduler".into(),
    })
}

/// A Slurm array task: index (ID − MIN) / STEP of COUNT tasks (COUNT, else (MAX − MIN) / STEP
/// + 1). Arrays given as lists (`--array=1,4,9`) have no uniform step and are refused.
fn slurm(
    id: i64,
    count: Option<usize>,
    var: &impl Fn(&str) -> Option<String>,
) -> Result<ShardSource> {
    let min = read_i64(var, "SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
    let step = read_i64(var, "SLURM_ARRAY_TASK_STEP")?.unwrap_or(1);
    let max = read_i64(var, "SLURM_ARRAY_TASK_MAX")?;
    let task_count = read_usize(var, "SLURM_ARRAY_TASK_COUNT")?;
    if step <= 0 {
        return Err(Error::invalid(
            "SLURM_ARRAY_TASK_STEP",
            format!("must be >= 1, got {step}"),
        ));
    }
    let from_max = match max {
        Some(max) if max >= min => Some(((max - min) / step + 1) as usize),
        Some(max) => {
            return Err(Error::invalid(
                "SLURM_ARRAY_TASK_MAX",
                format!("{max} is below SLURM_ARRAY_TASK_MIN={min}"),
            ));
        }
        None => None,
    };
    let n = match (task_count, from_max) {
        (Some(c), Some(m)) if c != m => {
            return Err(Error::invalid(
                "SLURM_ARRAY_TASK_COUNT",
                format!(
                    "{c} tasks, but MIN={min}, MAX={}, STEP={step} make {m}: the array is not a \
                     uniform range (use --array=A-B[:S], or pass --shard K/N)",
                    max.unwrap_or_default()
                ),
            ));
        }
        (Some(c), _) => c,
        (None, Some(m)) => m,
        (None, None) => {
            return Err(Error::invalid(
                "SLURM_ARRAY_TASK_COUNT",
                "SLURM_ARRAY_TASK_ID is set but neither SLURM_ARRAY_TASK_COUNT nor \
                 SLURM_ARRAY_TASK_MAX is: cannot tell the number of shards",
            ));
        }
    };
    let offset = id - min;
    if offset < 0 || offset % step != 0 || (offset / step) as usize >= n {
        return Err(Error::invalid(
            "SLURM_ARRAY_TASK_ID",
            format!(
                "task {id} is not one of the {n} tasks MIN={min}, STEP={step} (use a uniform \
                 --array=A-B[:S], or pass --shard K/N)"
            ),
        ));
    }
    if let Some(c) = count
        && c != n
    {
        return Err(Error::invalid(
            "--shards",
            format!("--shards/PINS_SHARD_COUNT says {c}, the Slurm array has {n} tasks"),
        ));
    }
    let index = (offset / step) as usize;
    Ok(ShardSource {
        shard: Shard { index, count: n },
        origin: format!(
            "Slurm job array (SLURM_ARRAY_TASK_ID={id}, MIN={min}, STEP={step}, {n} tasks)"
        ),
    })
}

fn read_i64(var: &impl Fn(&str) -> Option<String>, name: &str) -> Result<Option<i64>> {
    var(name)
        .filter(|v| !v.trim().is_empty())
        .map(|v| {
            v.trim()
                .parse::<i64>()
                .map_err(|_| Error::invalid(name, format!("expected an integer, got {v:?}")))
        })
        .transpose()
}

fn read_usize(var: &impl Fn(&str) -> Option<String>, name: &str) -> Result<Option<usize>> {
    var(name)
        .filter(|v| !v.trim().is_empty())
        .map(|v| {
            v.trim().parse::<usize>().map_err(|_| {
                Error::invalid(name, format!("expected a non-negative integer, got {v:?}"))
            })
        })
        .transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(pairs: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            pairs
                .iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    fn shard(flag: Option<&str>, shards: Option<usize>, pairs: &[(&str, &str)]) -> Result<Shard> {
        resolve(flag, shards, env(pairs)).map(|s| s.shard)
    }

    #[test]
    fn slurm_arrays_starting_at_one_or_with_a_step() {
        let s = |id: &str| {
            shard(
                None,
                None,
                &[
                    ("SLURM_ARRAY_TASK_ID", id),
                    ("SLURM_ARRAY_TASK_MIN", "1"),
                    ("SLURM_ARRAY_TASK_MAX", "7"),
                    ("SLURM_ARRAY_TASK_STEP", "2"),
                    ("SLURM_ARRAY_TASK_COUNT", "4"),
                ],
            )
        };
        for (id, k) in [("1", 0), ("3", 1), ("5", 2), ("7", 3)] {
            assert_eq!(s(id).expect(id), Shard { index: k, count: 4 });
        }
        // Not a task of that range.
        assert!(s("4").is_err() && s("9").is_err() && s("-1").is_err());
        // --array=0-9: COUNT alone suffices, MIN and STEP default to 0 and 1.
        let s = shard(
            None,
            None,
            &[
                ("SLURM_ARRAY_TASK_ID", "9"),
                ("SLURM_ARRAY_TASK_COUNT", "10"),
            ],
        );
        assert_eq!(
            s.expect("0-9"),
            Shard {
                index: 9,
                count: 10
            }
        );
    }

    #[test]
    fn list_arrays_and_inconsistent_values_are_errors() {
        // --array=1,4,9: COUNT 3, MIN 1, MAX 9, STEP 1 → not a range.
        let e = shard(
            None,
            None,
            &[
                ("SLURM_ARRAY_TASK_ID", "4"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_MAX", "9"),
                ("SLURM_ARRAY_TASK_STEP", "1"),
                ("SLURM_ARRAY_TASK_COUNT", "3"),
            ],
        )
        .expect_err("a list");
        assert!(e.to_string().contains("uniform"), "{e}");
        let e = shard(
            None,
            Some(5),
            &[
                ("SLURM_ARRAY_TASK_ID", "0"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ],
        )
        .expect_err("count clash");
        assert!(e.to_string().contains("4 tasks"), "{e}");
        let e = shard(None, None, &[("SLURM_ARRAY_TASK_ID", "x")]).expect_err("not a number");
        assert!(e.to_string().contains("SLURM_ARRAY_TASK_ID"), "{e}");
        let e = shard(None, None, &[("SLURM_ARRAY_TASK_ID", "2")]).expect_err("no count");
        assert!(e.to_string().contains("SLURM_ARRAY_TASK_COUNT"), "{e}");
        let e = shard(None, Some(3), &[("PINS_SHARD_COUNT", "4")]).expect_err("clash");
        assert!(e.to_string().contains("PINS_SHARD_COUNT=4"), "{e}");
        let e = shard(None, Some(3), &[]).expect_err("count without index");
        assert!(e.to_string().contains("no shard index"), "{e}");
    }

    #[test]
    fn kubernetes_indexed_jobs_need_the_count() {
        let pairs = [("JOB_COMPLETION_INDEX", "2")];
        let e = shard(None, None, &pairs).expect_err("no count");
        assert!(e.to_string().contains("--shards"), "{e}");
        assert_eq!(
            shard(None, Some(3), &pairs).expect("3"),
            Shard { index: 2, count: 3 }
        );
        let with_env = [("JOB_COMPLETION_INDEX", "2"), ("PINS_SHARD_COUNT", "5")];
        assert_eq!(
            shard(None, None, &with_env).expect("5"),
            Shard { index: 2, count: 5 }
        );
        assert!(shard(None, Some(2), &pairs).is_err(), "index 2 of 2");
    }

    #[test]
    fn the_flag_wins_and_nothing_means_everything() {
        let slurm = [
            ("SLURM_ARRAY_TASK_ID", "3"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ];
        let s = resolve(Some("1/2"), None, env(&slurm)).expect("flag");
        assert_eq!(s.shard, Shard { index: 1, count: 2 });
        assert!(s.origin.contains("--shard"));
        assert_eq!(shard(None, None, &[]).expect("none"), Shard::ALL);
        assert!(
            shard(Some("1/2"), Some(3), &[]).is_err(),
            "--shard 1/2 with --shards 3"
        );
        let s = resolve(None, None, env(&slurm)).expect("slurm");
        assert!(s.origin.contains("Slurm"), "{}", s.origin);
    }
}
