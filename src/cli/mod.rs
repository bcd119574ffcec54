//! The command line: argument definitions and one runner per command.
//!
//! Results go to stdout (text, or JSON with `--json`); progress, warnings and
//! errors go to stderr. Exit codes: 0 success, 1 failure not caused by the input,
//! 2 bad input or usage (see [`crate::error`]).

/// Writes results to stdout as `print!` does, returning from the enclosing function
/// with the error of a failed write ([`write_stdout`]), where `print!` would panic.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cli::write_stdout(format_args!($($arg)*))?
    };
}

/// [`out!`] with a newline, as `println!`.
macro_rules! outln {
    () => {
        $crate::cli::write_stdout(format_args!("\n"))?
    };
    ($($arg:tt)*) => {
        $crate::cli::write_stdout(format_args!("{}\n", format_args!($($arg)*)))?
    };
}

mod acf;
mod adev;
mod analyze;
mod batch;
mod cache;
mod check;
mod choices;
mod fit;
mod gap;
mod info;
mod ingest;
mod prep;
mod psd;
mod select;
mod simulate;
mod update;

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

use crate::error::{EXIT_OK, Error, Result};
use crate::log::{CachePolicy, Delimiter, LogOptions, Progress};
use choices::{GapArg, NanArg};

/// farma: nonparametric ARMA models of gyro drift, and where a simulator differs from the real sensor.
#[derive(Parser, Debug)]
#[command(
    name = "farma",
    version,
    about,
    long_about = None,
    after_help = "Formats and contracts (the log, the simulation spec with every component and unit, the gap JSON, the --json keys): docs/contracts.md in the repository; every table's columns: README.md."
)]
pub struct Cli {
    /// Worker threads (default: all cores; at most 4 per core).
    #[arg(long, global = true, value_name = "N")]
    pub threads: Option<usize>,
    /// No progress bars.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// Memory one request may plan, GB (default: half of the physical memory): a
    /// flag asking for more (--duration, --bootstrap, --replicas, --max-lag, ...) is
    /// refused before the work.
    #[arg(long, global = true, value_name = "GB")]
    pub memory_limit: Option<f64>,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Convert a log (CSV, Parquet, Arrow IPC) into a memory-mapped store.
    Ingest(ingest::IngestArgs),
    /// Channels, samples, rate, duration, gaps and per-channel statistics of a log.
    Info(info::InfoArgs),
    /// Fit a FARMA(p,q,d) model to channels of a log.
    Fit(fit::FitArgs),
    /// Overlapping Allan deviation (also modified Allan and Hadamard) with confidence intervals.
    Adev(adev::AdevArgs),
    /// Update fitted FARMA models with new samples (recursive least squares).
    Update(update::UpdateArgs),
    /// One-sided power spectral density of channels (Welch: Hann window, 50 % overlap).
    Psd(psd::PsdArgs),
    /// Autocorrelation of channels up to a maximum lag, with the +-1.96/sqrt(N) band.
    Acf(acf::AcfArgs),
    /// Prepare channels as the paper does: Pauta outliers, stationarity test, trend or differencing, mean.
    Prep(prep::PrepArgs),
    /// Compare FARMA orders (RSS, GCV, AICc, F-tests, ARMA baseline, constancy test) and pick one.
    Select(select::SelectArgs),
    /// The paper's workflow for every channel: prep, select, fit, check; all tables in one folder.
    Analyze(analyze::AnalyzeArgs),
    /// Check a fitted model on a log: residual whiteness, hold-out prediction vs ARMA, polynomial f_m.
    Check(check::CheckArgs),
    /// Run a job file's tasks over many logs into one partitioned Parquet dataset (resumable, shardable).
    Batch(batch::BatchArgs),
    /// The converted stores kept between runs: list them, or prune the least recently used.
    Cache(cache::CacheArgs),
    /// Simulate a gyro log from a simulation spec (TOML).
    Simulate(simulate::SimulateArgs),
    /// Where a simulation spec differs from a real log, which effect it misses, how far the gap shrinks.
    Gap(gap::GapArgs),
}

/// How to read the input log (shared by every command that reads one).
#[derive(Args, Debug, Clone)]
pub struct LogArgs {
    /// Time column in seconds (default: time, time_s, t or timestamp if present).
    #[arg(long, value_name = "NAME")]
    pub time_col: Option<String>,
    /// Sample rate in Hz, when there is no time column and no sample_rate_hz metadata.
    #[arg(long, value_name = "HZ")]
    pub rate: Option<f64>,
    /// CSV separator: , ; tab whitespace (default: detected from the header).
    #[arg(long, value_name = "SEP")]
    pub delimiter: Option<String>,
    /// NaN, Inf or empty cells in a channel.
    #[arg(long = "nan", value_enum, default_value_t = NanArg::Reject)]
    pub nan: NanArg,
    /// Gaps or irregular sampling in the time column.
    #[arg(long = "gaps", value_enum, default_value_t = GapArg::Reject)]
    pub gaps: GapArg,
    /// Relative tolerance on the sampling interval before it counts as irregular.
    #[arg(long, default_value_t = 0.05, value_name = "FRACTION")]
    pub time_tol: f64,
    /// Keep only these columns (comma-separated; the time column is always kept).
    #[arg(long, value_name = "A,B,..", value_delimiter = ',')]
    pub columns: Option<Vec<String>>,
    /// Folder for converted stores (default: $FARMA_CACHE_DIR, else ~/.cache/farma).
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Convert into a temporary store instead of the cache.
    #[arg(long, conflicts_with = "cache_dir")]
    pub no_cache: bool,
}

impl LogArgs {
    pub fn options(&self) -> Result<LogOptions> {
        Ok(LogOptions {
            time_col: self.time_col.clone(),
            rate_hz: self.rate,
            delimiter: self
                .delimiter
                .as_deref()
                .map(Delimiter::parse)
                .transpose()?,
            nan_policy: self.nan.into(),
            gap_policy: self.gaps.into(),
            time_tol: self.time_tol,
            columns: self.columns.clone(),
        })
    }

    /// Opens `path` as a store with these options (converting through the cache).
    pub fn open(&self, path: &std::path::Path, progress: &Progress) -> Result<crate::store::Store> {
        crate::log::open_log(path, &self.options()?, &self.cache(), progress)
    }

    pub fn cache(&self) -> CachePolicy {
        match (&self.cache_dir, self.no_cache) {
            (_, true) => CachePolicy::Off,
            (Some(d), false) => CachePolicy::Dir(d.clone()),
            (None, false) => CachePolicy::Default,
        }
    }
}

/// Runs the command line and returns the process exit code.
pub fn main() -> i32 {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) | Err(Error::StdoutClosed) => EXIT_OK,
        Err(e) => {
            eprintln!("farma: error: {e}");
            e.exit_code()
        }
    }
}

/// Writes results to stdout. A reader that closed the pipe (`| head`) gives
/// [`Error::StdoutClosed`] (exit 0, nothing more printed); any other failure (a full
/// disk behind `> file`) an [`Error::OutputIo`] on `<stdout>` (exit 1).
pub(crate) fn write_stdout(args: std::fmt::Arguments) -> Result<()> {
    use std::io::Write;
    std::io::stdout()
        .lock()
        .write_fmt(args)
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::BrokenPipe => Error::StdoutClosed,
            _ => Error::output_io(std::path::Path::new("<stdout>"), e),
        })
}

/// `--threads` is capped at this many threads per available core.
pub const MAX_THREADS_PER_CORE: usize = 4;

/// Runs parsed arguments.
pub fn run(cli: Cli) -> Result<()> {
    if let Some(n) = cli.threads {
        if n == 0 {
            return Err(Error::Usage("--threads must be at least 1".into()));
        }
        // far more threads than cores only adds switching, and a moment table per
        // thread in flight (1000 threads on 2 cores took a minute on 2000 samples):
        // the results do not depend on the number of threads, so it is capped
        let cores = std::thread::available_parallelism().map_or(n, |c| c.get());
        let cap = MAX_THREADS_PER_CORE * cores;
        let n = if n > cap {
            eprintln!(
                "farma: warning: --threads {n} is far more than the {cores} cores available; using {cap} (the results are the same with any number of threads)"
            );
            cap
        } else {
            n
        };
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| Error::Internal(format!("thread pool: {e}")))?;
    }
    if let Some(gb) = cli.memory_limit {
        crate::workflow::budget::set_memory_limit_gb(gb)?;
    }
    let progress = Progress::auto(cli.quiet);
    match cli.command {
        Command::Ingest(a) => ingest::run(a, &progress),
        Command::Info(a) => info::run(a, &progress),
        Command::Fit(a) => fit::run(a, &progress),
        Command::Adev(a) => adev::run(a, &progress),
        Command::Update(a) => update::run(a, &progress),
        Command::Psd(a) => psd::run(a, &progress),
        Command::Acf(a) => acf::run(a, &progress),
        Command::Prep(a) => prep::run(a, &progress),
        Command::Select(a) => select::run(a, &progress),
        Command::Analyze(a) => analyze::run(a, &progress),
        Command::Batch(a) => batch::run(a, &progress),
        Command::Cache(a) => cache::run(a),
        Command::Check(a) => check::run(a, &progress),
        Command::Simulate(a) => simulate::run(a, &progress),
        Command::Gap(a) => gap::run(a, &progress),
    }
}
