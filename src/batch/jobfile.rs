//! The job file of `farma batch` (TOML): the inputs, the channel roles, the tasks and
//! the output root. Read and checked once ([`JobFile::load`]); every error names the
//! file and the key.
//!
//! ```toml
//! output = "nightly-out"                  # the dataset root (-o overrides it)
//!
//! [[inputs]]                              # files, globs (* ? [..]) or folders
//! paths = ["logs/*.parquet", "stand3/"]   # relative to the job file's folder
//! channels = ["gyro_x", "gyro_y"]         # optional; default: the gyro role
//! optional = false                        # true: skip paths that name no file
//! gyro = ["rate_*"]                       # optional; these logs' gyro patterns
//!
//! [roles]                                 # optional; channel-name patterns
//! gyro = ["*gyro*", "*_dps", "rate*"]     # default: crate::log::roles::GYRO_PATTERNS
//! temperature = ["temp*", "*_degc"]       # default: TEMPERATURE_PATTERNS
//! accel = ["*accel*", "*_g"]              # default: ACCEL_PATTERNS
//!
//! [[tasks]]
//! kind = "fit"                            # adev | psd | fit | analyze | select | prep | check
//! name = "fit211"                         # optional, default the kind; unique
//! order = "2,1,1"
//! ```
//!
//! Task options (each optional, the command's default otherwise): `adev`:
//! `fit_tau_min` (the octave Allan deviation with one-sigma intervals and the noise
//! terms, as `farma adev` gives them); `psd`: `segment` (samples), `detrend`
//! (constant, none), `bands_per_decade` (0, the default: every bin); `fit`: `order`,
//! `grid`, `bandwidth`, `method` (fast, direct), `max_iter`, `tol`, `residuals`;
//! `select`: `orders`, `grid`, `method`, `constancy` (chi2, bootstrap, none),
//! `bootstrap`, `seed`; `analyze`: those of
//! `select` and `holdout_s`, `maxlag`, `max_degree`; `check`: `model` (a model folder
//! of `farma fit`, relative to the job file; required), `holdout_s`, `maxlag`,
//! `max_degree`; `prep`: none (the defaults of
//! `farma prep`); `gap`: `spec` (a simulation spec, relative to the job file;
//! required; the unit's channels that the spec has are diagnosed, and the log's first
//! channel of the temperature role is offered when the spec names no
//! `temperature_channel`), `replicas`, `blocks`, `train_fraction`, `seed`, `max_effects`,
//! `reestimate` (true: `farma gap --reestimate`), `keep_events` (true: `farma gap
//! --keep-events`), `explain_replicas` (`farma gap --explain-replicas`), `max_samples`
//! (`farma gap --max-samples`), `excerpt_samples` (`farma gap --excerpt-samples`) (the defaults
//! of `farma gap`). A folder input takes its `.csv`, `.parquet`, `.arrow` and `.ipc`
//! files (not recursively).

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::error::{Error, Result};

pub use crate::log::roles::{GYRO_PATTERNS, Roles, TEMPERATURE_PATTERNS, name_matches};

/// A job file, parsed and checked.
#[derive(Clone, Debug)]
pub struct JobFile {
    /// The file it was read from.
    pub path: PathBuf,
    /// The dataset root (resolved against the job file's folder), if given.
    pub output: Option<PathBuf>,
    pub inputs: Vec<Input>,
    pub roles: Roles,
    pub tasks: Vec<Task>,
}

/// One `[[inputs]]` entry.
#[derive(Clone, Debug)]
pub struct Input {
    /// Files, globs or folders, resolved against the job file's folder.
    pub paths: Vec<PathBuf>,
    /// The channels of its logs; `None`: the gyro role.
    pub channels: Option<Vec<String>>,
    /// A path that names no file is skipped with a warning instead of an error (logs
    /// that are present on some machines only).
    pub optional: bool,
    /// The gyro role's patterns for these logs, overriding `[roles] gyro`.
    pub gyro: Option<Vec<String>>,
}

/// What a task runs on each log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TaskKind {
    Adev,
    Psd,
    Check,
    Fit,
    Analyze,
    Select,
    Prep,
    Gap,
}

impl TaskKind {
    pub fn as_str(&self) -> &'static str {
        match self {
            TaskKind::Adev => "adev",
            TaskKind::Psd => "psd",
            TaskKind::Check => "check",
            TaskKind::Fit => "fit",
            TaskKind::Analyze => "analyze",
            TaskKind::Select => "select",
            TaskKind::Prep => "prep",
            TaskKind::Gap => "gap",
        }
    }
}

/// One `[[tasks]]` entry.
#[derive(Clone, Debug)]
pub struct Task {
    pub kind: TaskKind,
    /// Unique within the job; a directory and partition name.
    pub name: String,
    /// The task's table as written (its options, canonical TOML): what the options
    /// hash of a unit is taken over.
    pub options: toml::Table,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJob {
    output: Option<String>,
    #[serde(default)]
    inputs: Vec<RawInput>,
    roles: Option<RawRoles>,
    #[serde(default)]
    tasks: Vec<toml::Table>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInput {
    paths: Vec<String>,
    channels: Option<Vec<String>>,
    #[serde(default)]
    optional: bool,
    gyro: Option<Vec<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRoles {
    gyro: Option<Vec<String>>,
    temperature: Option<Vec<String>>,
    accel: Option<Vec<String>>,
}

/// The keys each task kind takes (besides `kind` and `name`).
fn task_keys(kind: &TaskKind) -> &'static [&'static str] {
    match kind {
        TaskKind::Adev => &["fit_tau_min"],
        TaskKind::Psd => &["segment", "detrend", "bands_per_decade"],
        TaskKind::Check => &["model", "holdout_s", "maxlag", "max_degree"],
        TaskKind::Fit => &[
            "order",
            "grid",
            "bandwidth",
            "method",
            "max_iter",
            "tol",
            "residuals",
        ],
        TaskKind::Select => &["orders", "grid", "method", "constancy", "bootstrap", "seed"],
        TaskKind::Analyze => &[
            "orders",
            "grid",
            "method",
            "constancy",
            "bootstrap",
            "seed",
            "holdout_s",
            "maxlag",
            "max_degree",
        ],
        TaskKind::Prep => &[],
        TaskKind::Gap => &[
            "spec",
            "replicas",
            "blocks",
            "train_fraction",
            "seed",
            "max_effects",
            "reestimate",
            "screen",
            "joint_pairs",
            "keep_events",
            "explain_replicas",
            "max_samples",
            "excerpt_samples",
        ],
    }
}

impl JobFile {
    /// Reads and checks the job file at `path`.
    pub fn load(path: &Path) -> Result<JobFile> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::input_io(path, e))?;
        JobFile::parse(path, &text)
    }

    /// Parses `text` as the job file `path` (relative paths resolve against its folder).
    pub fn parse(path: &Path, text: &str) -> Result<JobFile> {
        let bad = |msg: String| Error::format(path, msg);
        let raw: RawJob = toml::from_str(text).map_err(|e| bad(format!("not a job file: {e}")))?;
        let base = path.parent().unwrap_or(Path::new("."));
        let resolve = |p: &str| -> PathBuf {
            let p = Path::new(p);
            if p.is_absolute() {
                p.to_path_buf()
            } else {
                base.join(p)
            }
        };
        if raw.inputs.is_empty() {
            return Err(bad("no [[inputs]]: name the logs to run on".into()));
        }
        let mut inputs = Vec::new();
        for (i, inp) in raw.inputs.into_iter().enumerate() {
            if inp.paths.is_empty() {
                return Err(bad(format!("inputs[{i}].paths is empty")));
            }
            if let Some(c) = &inp.channels
                && c.is_empty()
            {
                return Err(bad(format!(
                    "inputs[{i}].channels is empty (leave it out for the gyro channels)"
                )));
            }
            inputs.push(Input {
                paths: inp.paths.iter().map(|p| resolve(p)).collect(),
                channels: inp.channels,
                optional: inp.optional,
                gyro: inp.gyro,
            });
        }
        let roles = match raw.roles {
            None => Roles::default(),
            Some(r) => {
                let d = Roles::default();
                Roles {
                    gyro: r.gyro.unwrap_or(d.gyro),
                    temperature: r.temperature.unwrap_or(d.temperature),
                    accel: r.accel.unwrap_or(d.accel),
                    overrides: Vec::new(),
                }
            }
        };
        if raw.tasks.is_empty() {
            return Err(bad("no [[tasks]]: name what to run on each log".into()));
        }
        let mut tasks: Vec<Task> = Vec::new();
        for (i, t) in raw.tasks.into_iter().enumerate() {
            let kind = match t.get("kind").and_then(|v| v.as_str()) {
                Some("adev") => TaskKind::Adev,
                Some("psd") => TaskKind::Psd,
                Some("check") => TaskKind::Check,
                Some("fit") => TaskKind::Fit,
                Some("analyze") => TaskKind::Analyze,
                Some("select") => TaskKind::Select,
                Some("prep") => TaskKind::Prep,
                Some("gap") => TaskKind::Gap,
                Some(k) => {
                    return Err(bad(format!(
                        "tasks[{i}].kind = '{k}': not one of adev, psd, fit, analyze, select, prep, check, gap"
                    )));
                }
                None => {
                    return Err(bad(format!(
                        "tasks[{i}]: no kind (adev, psd, fit, analyze, select, prep, check, gap)"
                    )));
                }
            };
            let name = match t.get("name") {
                None => kind.as_str().to_string(),
                Some(v) => v
                    .as_str()
                    .ok_or_else(|| bad(format!("tasks[{i}].name is not a string")))?
                    .to_string(),
            };
            if name.is_empty()
                || !name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            {
                return Err(bad(format!(
                    "tasks[{i}].name = '{name}': letters, digits, _ and - only (it names folders)"
                )));
            }
            if tasks.iter().any(|o| o.name == name) {
                return Err(bad(format!(
                    "tasks[{i}]: the name '{name}' is taken by another task; give each task of a kind a name"
                )));
            }
            let allowed = task_keys(&kind);
            let mut options = toml::Table::new();
            for (k, v) in &t {
                if k == "kind" || k == "name" {
                    continue;
                }
                if !allowed.contains(&k.as_str()) {
                    return Err(bad(format!(
                        "tasks[{i}] ({}): unknown key '{k}'; it takes {}",
                        kind.as_str(),
                        if allowed.is_empty() {
                            "no options".to_string()
                        } else {
                            allowed.join(", ")
                        }
                    )));
                }
                options.insert(k.clone(), v.clone());
            }
            if kind == TaskKind::Check {
                let model = options
                    .get("model")
                    .and_then(|v| v.as_str())
                    .ok_or_else(|| {
                        bad(format!(
                            "tasks[{i}] (check): no model = \"FOLDER\" (the output folder of farma fit)"
                        ))
                    })?;
                let abs = resolve(model).display().to_string();
                options.insert("model".into(), toml::Value::String(abs));
            }
            if kind == TaskKind::Gap {
                let spec = options
                    .get("spec")
                    .and_then(|v| v.as_str())
                    .ok_or_else(|| {
                        bad(format!(
                            "tasks[{i}] (gap): no spec = \"FILE\" (the simulation spec to diagnose)"
                        ))
                    })?;
                let abs = resolve(spec).display().to_string();
                options.insert("spec".into(), toml::Value::String(abs));
            }
            tasks.push(Task {
                kind,
                name,
                options,
            });
        }
        Ok(JobFile {
            path: path.to_path_buf(),
            output: raw.output.as_deref().map(resolve),
            inputs,
            roles,
            tasks,
        })
    }
}

/// A task option as an unsigned integer.
pub fn opt_usize(t: &Task, key: &str) -> Result<Option<usize>> {
    match t.options.get(key) {
        None => Ok(None),
        Some(v) => v
            .as_integer()
            .and_then(|i| usize::try_from(i).ok())
            .map(Some)
            .ok_or_else(|| {
                Error::Usage(format!(
                    "task '{}': {key} = {v} is not a non-negative integer",
                    t.name
                ))
            }),
    }
}

/// A task option as a number.
pub fn opt_f64(t: &Task, key: &str) -> Result<Option<f64>> {
    match t.options.get(key) {
        None => Ok(None),
        Some(v) => v
            .as_float()
            .or_else(|| v.as_integer().map(|i| i as f64))
            .map(Some)
            .ok_or_else(|| Error::Usage(format!("task '{}': {key} = {v} is not a number", t.name))),
    }
}

/// A task option as a string.
pub fn opt_str<'a>(t: &'a Task, key: &str) -> Result<Option<&'a str>> {
    match t.options.get(key) {
        None => Ok(None),
        Some(v) => v
            .as_str()
            .map(Some)
            .ok_or_else(|| Error::Usage(format!("task '{}': {key} = {v} is not a string", t.name))),
    }
}

/// A task option as a boolean.
pub fn opt_bool(t: &Task, key: &str) -> Result<Option<bool>> {
    match t.options.get(key) {
        None => Ok(None),
        Some(v) => v.as_bool().map(Some).ok_or_else(|| {
            Error::Usage(format!(
                "task '{}': {key} = {v} is not true or false",
                t.name
            ))
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_job_file_parses_and_bad_keys_are_named() {
        let p = Path::new("/jobs/n.toml");
        let j = JobFile::parse(
            p,
            "output = \"out\"\n[[inputs]]\npaths = [\"a.csv\", \"/abs/*.parquet\"]\n[[tasks]]\nkind = \"fit\"\norder = \"2,1,1\"\n[[tasks]]\nkind = \"analyze\"\nname = \"quick\"\nbootstrap = 0\n",
        )
        .unwrap();
        assert_eq!(j.output.as_deref(), Some(Path::new("/jobs/out")));
        assert_eq!(j.inputs[0].paths[0], Path::new("/jobs/a.csv"));
        assert_eq!(j.inputs[0].paths[1], Path::new("/abs/*.parquet"));
        assert_eq!(j.tasks.len(), 2);
        assert_eq!(j.tasks[1].name, "quick");
        assert!(j.roles.is_gyro("gyro_x") && j.roles.is_gyro("Rate_X_DPS"));
        assert!(!j.roles.is_gyro("accel_x_g") && j.roles.is_temperature("temp_c"));
        let e = JobFile::parse(
            p,
            "[[inputs]]\npaths = [\"a.csv\"]\n[[tasks]]\nkind = \"fit\"\nordre = \"2,1,1\"\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("n.toml") && e.contains("ordre"), "{e}");
        let e = JobFile::parse(p, "[[inputs]]\npaths = [\"a.csv\"]\n[[tasks]]\nkind = \"fit\"\n[[tasks]]\nkind = \"fit\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("taken"), "{e}");
        assert!(JobFile::parse(p, "[[tasks]]\nkind = \"fit\"\n").is_err());
    }
}
