//! Which share of the jobs this process runs: `--shard I/N` (1-based, as
//! people count), or the array variables of the scheduler the cluster
//! already has — Slurm job arrays (`SLURM_ARRAY_TASK_ID`,
//! `SLURM_ARRAY_TASK_COUNT`, `SLURM_ARRAY_TASK_MIN`) or Kubernetes indexed
//! jobs (`JOB_COMPLETION_INDEX` with `--shard-count`). Job i goes to shard
//! i mod N, so every job runs exactly once over the N shards.

/// `(index, count)` with a 0-based index; errors name the setting (`shard`,
/// `shard_count`) or the variable.
pub fn resolve(explicit: Option<&str>, shard_count: Option<usize>, env: &dyn Fn(&str) -> Option<String>) -> crate::Result<(usize, usize)> {
    resolve_inner(explicit, shard_count, env).map_err(|(setting, msg)| match setting {
        Some(setting) => crate::Error::setting(setting, msg),
        None => crate::Error::Usage(msg),
    })
}

/// The setting at fault, or none (a variable of the environment, which
/// the message names).
type Problem = (Option<&'static str>, String);

fn resolve_inner(explicit: Option<&str>, shard_count: Option<usize>, env: &dyn Fn(&str) -> Option<String>) -> Result<(usize, usize), Problem> {
    let num = |v: String, what: &str| v.trim().parse::<usize>().map_err(|_| (None, format!("{what}='{v}' is not a whole number")));
    if let Some(s) = explicit {
        let bad = || (Some("shard"), format!("'{s}' is not I/N with I in 1..=N"));
        if shard_count.is_some() {
            return Err((Some("shard_count"), format!("goes with an index the scheduler sets (JOB_COMPLETION_INDEX), but ‹shard› {s} gives both")));
        }
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (i, n) = (i.trim().parse::<usize>().map_err(|_| bad())?, n.trim().parse::<usize>().map_err(|_| bad())?);
        if n == 0 || i == 0 || i > n {
            return Err(bad());
        }
        return Ok((i - 1, n));
    }
    if let Some(id) = env("SLURM_ARRAY_TASK_ID") {
        let id = num(id, "SLURM_ARRAY_TASK_ID")?;
        let count = match (env("SLURM_ARRAY_TASK_COUNT"), shard_count) {
            (_, Some(n)) => n,
            (Some(c), None) => num(c, "SLURM_ARRAY_TASK_COUNT")?,
            (None, None) => return Err((Some("shard_count"), "SLURM_ARRAY_TASK_ID is set but not SLURM_ARRAY_TASK_COUNT: give the number of shares".into())),
        };
        let min = env("SLURM_ARRAY_TASK_MIN").map(|m| num(m, "SLURM_ARRAY_TASK_MIN")).transpose()?.unwrap_or(0);
        let i = id.checked_sub(min).filter(|&i| i < count).ok_or_else(|| {
            (None, format!("SLURM_ARRAY_TASK_ID {id} is not one of the array's {count} tasks, {min} to {} (SLURM_ARRAY_TASK_MIN, and SLURM_ARRAY_TASK_COUNT or ‹shard_count›)", min + count - 1))
        })?;
        return Ok((i, count));
    }
    if let Some(idx) = env("JOB_COMPLETION_INDEX") {
        let i = num(idx, "JOB_COMPLETION_INDEX")?;
        let n = shard_count.ok_or((Some("shard_count"), "JOB_COMPLETION_INDEX is set: give the number of shares (the Job's completions)".to_string()))?;
        if i >= n {
            return Err((Some("shard_count"), format!("JOB_COMPLETION_INDEX {i} is not below the number of shares, {n}")));
        }
        return Ok((i, n));
    }
    // A count without an index: every pod of a Job that is not Indexed
    // would run every job.
    if let Some(n) = shard_count {
        return Err((
            Some("shard_count"),
            format!("{n} shares, but neither JOB_COMPLETION_INDEX (a Kubernetes Indexed Job) nor SLURM_ARRAY_TASK_ID is set: this process would run every job; run it as an indexed job, or give ‹shard› I/{n}"),
        ));
    }
    Ok((0, 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(vars: &'static [(&'static str, &'static str)]) -> impl Fn(&str) -> Option<String> {
        move |k| vars.iter().find(|(n, _)| *n == k).map(|(_, v)| v.to_string())
    }

    #[test]
    fn explicit_slurm_and_kubernetes() {
        assert_eq!(resolve(Some("2/3"), None, &env(&[])).ok(), Some((1, 3)));
        assert!(resolve(Some("0/3"), None, &env(&[])).is_err());
        assert_eq!(
            resolve(None, None, &env(&[("SLURM_ARRAY_TASK_ID", "5"), ("SLURM_ARRAY_TASK_COUNT", "4"), ("SLURM_ARRAY_TASK_MIN", "3")])).ok(),
            Some((2, 4))
        );
        assert_eq!(resolve(None, None, &env(&[("SLURM_ARRAY_TASK_ID", "0"), ("SLURM_ARRAY_TASK_COUNT", "2")])).ok(), Some((0, 2)));
        assert_eq!(resolve(None, Some(5), &env(&[("JOB_COMPLETION_INDEX", "4")])).ok(), Some((4, 5)));
        assert!(resolve(None, None, &env(&[("JOB_COMPLETION_INDEX", "4")])).is_err());
        assert_eq!(resolve(None, None, &env(&[])).ok(), Some((0, 1)));
    }

    /// A count with no index to go with it, or with --shard besides, is
    /// refused (a Job that is not Indexed would run every job in every
    /// pod); an index out of the array's range names the variables.
    #[test]
    fn a_count_without_an_index_and_an_index_out_of_range_are_refused() {
        let err = resolve(None, Some(3), &env(&[])).unwrap_err().to_string();
        assert!(err.contains("neither JOB_COMPLETION_INDEX") && err.contains("give shard I/3"), "{err}");
        assert!(resolve(Some("1/3"), Some(3), &env(&[])).is_err());
        let err = resolve(None, None, &env(&[("SLURM_ARRAY_TASK_ID", "3"), ("SLURM_ARRAY_TASK_COUNT", "3")])).unwrap_err();
        assert!(matches!(&err, crate::Error::Usage(m) if m.contains("not one of the array's 3 tasks, 0 to 2")), "{err}");
    }
}
