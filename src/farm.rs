//! What `retrace farm` reads from a Slurm cluster and from its tasks'
//! outputs: each array task's state as `scontrol` or `sacct` tells it, and
//! the share of each frame's pixels the chunks reused.

use serde_json::Value;

/// One job, or one task of an array job, as the scheduler reports it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TaskRecord {
    /// The job id (the array's, for an array task).
    pub job: String,
    /// The task's index in the array; a range (`2-3`) for tasks still
    /// pending together; None for a job that is not an array.
    pub task: Option<String>,
    pub name: String,
    /// PENDING, RUNNING, COMPLETED, FAILED, CANCELLED, ...
    pub state: String,
    /// Slurm's `exit:signal`, e.g. `1:0`, or `0:15` for a SIGTERM.
    pub exit_code: String,
    /// Times the task was requeued; None where the source does not say.
    pub restarts: Option<u32>,
    /// Why a job waits or failed (`Dependency`, `NonZeroExitCode`).
    pub reason: String,
}

impl TaskRecord {
    /// Ended without success: a failure, a cancellation, a time-out.
    pub fn failed(&self) -> bool {
        !matches!(
            self.state.as_str(),
            "COMPLETED" | "PENDING" | "RUNNING" | "COMPLETING" | "REQUEUED" | "CONFIGURING"
        ) && !self.state.starts_with("REQUEUE")
            && !self.state.is_empty()
    }

    /// Whether the scheduler is done with it, one way or the other.
    pub fn ended(&self) -> bool {
        self.state == "COMPLETED" || self.failed()
    }

    /// The exit code in words: `exit 1`, `signal 15`, `0`.
    pub fn exit_text(&self) -> String {
        match self.exit_code.split_once(':') {
            Some((_, signal)) if signal != "0" && !signal.is_empty() => format!("signal {signal}"),
            Some((code, _)) if code != "0" => format!("exit {code}"),
            Some(_) => "0".to_string(),
            None if self.exit_code.is_empty() => "-".to_string(),
            None => self.exit_code.clone(),
        }
    }
}

/// The records of `scontrol -o show job J`: one line a job, or a task of
/// an array (tasks still pending together share one line).
pub fn parse_scontrol(text: &str) -> Vec<TaskRecord> {
    text.lines()
        .filter(|line| line.contains("JobId="))
        .map(|line| {
            let mut record = TaskRecord::default();
            let mut job_id = String::new();
            for field in line.split_whitespace() {
                let Some((key, value)) = field.split_once('=') else {
                    continue;
                };
                let value = value.to_string();
                match key {
                    "JobId" => job_id = value,
                    "ArrayJobId" => record.job = value,
                    "ArrayTaskId" => record.task = Some(value),
                    "JobName" => record.name = value,
                    "JobState" => record.state = value,
                    "ExitCode" => record.exit_code = value,
                    "Restarts" => record.restarts = value.parse().ok(),
                    "Reason" => record.reason = value,
                    _ => {}
                }
            }
            if record.job.is_empty() {
                record.job = job_id;
            }
            if record.reason == "None" {
                record.reason.clear();
            }
            record
        })
        .collect()
}

/// The records of `sacct -n -P -X -o JobID,JobName,State,ExitCode,Reason`:
/// `1234_2|retrace-render|FAILED|1:0|NonZeroExitCode` (sacct does not count
/// restarts).
pub fn parse_sacct(text: &str) -> Vec<TaskRecord> {
    text.lines()
        .filter_map(|line| {
            let fields: Vec<&str> = line.trim().split('|').collect();
            let [id, name, state, exit_code, rest @ ..] = &fields[..] else {
                return None;
            };
            let (id, name, state, exit_code) = (*id, *name, *state, *exit_code);
            let (job, task) = match id.split_once('_') {
                Some((job, task)) => (job, Some(task.trim_matches(['[', ']']).to_string())),
                None => (id, None),
            };
            // "CANCELLED by 0": the state is the first word.
            let state = state.split_whitespace().next().unwrap_or_default();
            let reason = rest.first().copied().unwrap_or_default();
            Some(TaskRecord {
                job: job.to_string(),
                task,
                name: name.to_string(),
                state: state.to_string(),
                exit_code: exit_code.to_string(),
                restarts: None,
                reason: if reason == "None" { "" } else { reason }.to_string(),
            })
        })
        .collect()
}

/// Sorts records by job, then by task index (numerically; ranges by their
/// first index).
pub fn sort_records(records: &mut [TaskRecord]) {
    let first = |task: &Option<String>| {
        task.as_deref()
            .and_then(|t| t.split(['-', ',', '%']).next())
            .and_then(|t| t.parse::<u64>().ok())
            .unwrap_or(u64::MAX)
    };
    records.sort_by(|a, b| {
        (a.job.parse::<u64>().unwrap_or(u64::MAX), first(&a.task))
            .cmp(&(b.job.parse::<u64>().unwrap_or(u64::MAX), first(&b.task)))
    });
}

/// The share of a row's pixels that were reused instead of traced, 0 to 1.
pub fn reused_share(row: &Value) -> Option<f64> {
    let pixels = row.get("pixels")?.as_f64()?;
    let reused = row.get("pixels_reused")?.as_f64()?;
    (pixels > 0.0).then(|| reused / pixels)
}

/// The indices of an `ArrayTaskId` field: `3`, or `2-5` for tasks still
/// pending together (a `%` limit after them left off).
pub fn task_indices(field: &str) -> Vec<u32> {
    let field = field.split('%').next().unwrap_or_default();
    field
        .split(',')
        .flat_map(|part| match part.split_once('-') {
            Some((a, b)) => match (a.parse::<u32>(), b.parse::<u32>()) {
                (Ok(a), Ok(b)) => (a..=b).collect(),
                _ => Vec::new(),
            },
            None => part.parse().into_iter().collect(),
        })
        .collect()
}

/// What one chunk restart costs, in frames' worth of the reuse one long run
/// has, as `retrace bench --only chunking` measures it (docs/RESULTS.md):
/// a restarted chunk traces its first frame in full, and a viewport's
/// lazily traced buffer is filled again over its first few frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestartCost {
    pub frames: f64,
}

impl RestartCost {
    /// Pans and OSTC: the first frame is traced in full (measured 1.1
    /// frames on E1, 1.3 on E3).
    pub const EXACT: RestartCost = RestartCost { frames: 1.3 };
    /// RSVP viewports: an empty buffer besides (measured 3.6 frames on E4).
    pub const VIEWPORTS: RestartCost = RestartCost { frames: 3.6 };

    /// The share of a long run's reuse that cutting `frames` frames into
    /// `chunks` chunks loses (at most all of it).
    pub fn reuse_lost(self, chunks: u32, frames: u32) -> f64 {
        (self.frames * f64::from(chunks.saturating_sub(1)) / f64::from(frames.max(1))).min(1.0)
    }

    /// The fewest frames a chunk should have to lose less than `share` of
    /// the reuse.
    pub fn min_frames_per_chunk(self, share: f64) -> u32 {
        (self.frames / share).ceil().max(1.0) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunking_loses_one_restart_of_reuse_a_chunk() {
        let exact = RestartCost { frames: 1.0 };
        assert_eq!(exact.reuse_lost(1, 100), 0.0);
        assert!((exact.reuse_lost(11, 100) - 0.1).abs() < 1e-12);
        assert_eq!(exact.min_frames_per_chunk(0.1), 10);
        assert_eq!(RestartCost { frames: 3.6 }.min_frames_per_chunk(0.1), 36);
        // More chunks than restarts can lose is all of it, never more.
        assert_eq!(exact.reuse_lost(100, 10), 1.0);
    }

    #[test]
    fn scontrol_lines_give_each_task() {
        let text = "\
JobId=12 ArrayJobId=11 ArrayTaskId=1 JobName=retrace-render UserId=root(0) JobState=COMPLETED Reason=None Dependency=(null) Requeue=1 Restarts=0 ExitCode=0:0
JobId=13 ArrayJobId=11 ArrayTaskId=2 JobName=retrace-render JobState=FAILED Reason=NonZeroExitCode Restarts=1 ExitCode=1:0
JobId=11 ArrayJobId=11 ArrayTaskId=3-4 JobName=retrace-render JobState=PENDING Reason=Resources Restarts=0 ExitCode=0:0
JobId=15 JobName=retrace-assemble JobState=PENDING Reason=DependencyNeverSatisfied Restarts=0 ExitCode=0:0
";
        let records = parse_scontrol(text);
        assert_eq!(records.len(), 4);
        assert_eq!(records[0].job, "11");
        assert_eq!(records[0].task.as_deref(), Some("1"));
        assert_eq!(records[0].reason, "");
        assert!(records[0].ended() && !records[0].failed());
        let failed = &records[1];
        assert_eq!(
            (failed.state.as_str(), failed.restarts, failed.exit_text()),
            ("FAILED", Some(1), "exit 1".to_string())
        );
        assert!(failed.failed());
        assert_eq!(records[2].task.as_deref(), Some("3-4"));
        assert!(!records[2].ended());
        assert_eq!(records[3].job, "15");
        assert_eq!(records[3].task, None);
        assert_eq!(records[3].reason, "DependencyNeverSatisfied");
    }

    #[test]
    fn sacct_lines_give_each_task() {
        let text = "11_0|retrace-render|COMPLETED|0:0|None\n\
                    11_1|retrace-render|CANCELLED by 0|0:15|None\n\
                    11_[2-3]|retrace-render|PENDING|0:0|Resources\n";
        let mut records = parse_sacct(text);
        sort_records(&mut records);
        assert_eq!(records.len(), 3);
        assert_eq!(records[1].state, "CANCELLED");
        assert_eq!(records[1].exit_text(), "signal 15");
        assert!(records[1].failed());
        assert_eq!(records[2].task.as_deref(), Some("2-3"));
        assert_eq!(records[2].reason, "Resources");
        assert_eq!(records[0].restarts, None);
    }

    #[test]
    fn records_sort_by_task_number() {
        let record = |task: &str| TaskRecord {
            job: "7".into(),
            task: Some(task.into()),
            ..Default::default()
        };
        let mut records = vec![record("10"), record("2-3"), record("1")];
        sort_records(&mut records);
        let order: Vec<_> = records.iter().map(|r| r.task.clone().unwrap()).collect();
        assert_eq!(order, ["1", "2-3", "10"]);
    }

    #[test]
    fn the_reused_share_is_of_the_row_s_pixels() {
        let row = serde_json::json!({"frame": 0, "pixels": 4, "pixels_reused": 3});
        assert_eq!(reused_share(&row), Some(0.75));
        assert_eq!(
            reused_share(&serde_json::json!({"pixels": 0, "pixels_reused": 0})),
            None
        );
    }

    #[test]
    fn task_fields_give_their_indices() {
        assert_eq!(task_indices("3"), [3]);
        assert_eq!(task_indices("2-5%2"), [2, 3, 4, 5]);
        assert_eq!(task_indices("0,7-8"), [0, 7, 8]);
        assert!(task_indices("x").is_empty());
    }

    #[test]
    fn exit_codes_read_as_words() {
        let with = |code: &str| {
            TaskRecord {
                exit_code: code.into(),
                ..Default::default()
            }
            .exit_text()
        };
        assert_eq!(with("0:0"), "0");
        assert_eq!(with("7:0"), "exit 7");
        assert_eq!(with("0:9"), "signal 9");
        assert_eq!(with(""), "-");
    }
}
