//! `farma gap --real LOG --sim SPEC --channel NAME -o OUTDIR`: where a simulator differs
//! from the real sensor, which effect it misses, how far the gap shrinks.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use super::LogArgs;
use crate::diagnosis::{GapParams, diagnose_with_progress, report};
use crate::error::Result;
use crate::jobs::gap::GapJob;
use crate::log::Progress;
use crate::simulator::load_spec;

#[derive(Args, Debug)]
pub struct GapArgs {
    /// The real log: a store, CSV, Parquet or Arrow IPC.
    #[arg(long, value_name = "LOG")]
    pub real: PathBuf,
    /// The simulation spec (TOML, contracts.md section 2).
    #[arg(long, value_name = "SPEC")]
    pub sim: PathBuf,
    /// The channel to diagnose (a channel of the spec and of the log).
    #[arg(long)]
    pub channel: String,
    /// Share of the time blocks fold 1 uses to estimate effects, the rest withheld for
    /// scoring; fold 2 swaps the roles, so every block is scored once.
    #[arg(long, default_value_t = 0.5, value_name = "F")]
    pub train_fraction: f64,
    /// Simulations of the spec in the ensemble.
    #[arg(long, default_value_t = 20, value_name = "M")]
    pub replicas: usize,
    /// Interleaved time blocks the log is cut into (block 0 further cut into up to five
    /// alternating pieces).
    #[arg(long, default_value_t = 8, value_name = "N")]
    pub blocks: usize,
    /// Seed of the ensemble (default: the spec's seed, else 1).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Most effects the greedy search adds.
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub max_effects: usize,
    /// Estimate every kept effect again after each addition (by default only those
    /// estimated at the edge of a search range), and let a round's rivals compete with
    /// its best (each trial copies both folds' ensembles: about twice the peak memory,
    /// and more time).
    #[arg(long)]
    pub reestimate: bool,
    /// Score every candidate on every replica; by default a round's candidates are
    /// scored on a quarter of the replicas first (at M >= 20), and only those whose gap
    /// there is below 1.3 times the round's lowest are scored on the rest.
    #[arg(long)]
    pub no_screen: bool,
    /// Single candidates only; by default the first round also scores the two pairs of
    /// biases (constant bias, ramp, warm-up, sinusoid, temperature bias, thermal rate)
    /// that fit the training residual best when estimated together, and adds the
    /// better pair when it beats the round's best single effect by the margin a
    /// forward step needs and by more than a tie (two missing biases that bend each
    /// other's single fits)
    #[arg(long)]
    pub no_joint_pairs: bool,
    /// Keep test-stand events (shocks seen on the diagnosed channel and at least two
    /// other channels at once) in the real log; by default each is replaced by the
    /// stretch before it and listed in `events_excluded`.
    #[arg(long)]
    pub keep_events: bool,
    /// Simulations of the spec after diagnosed again (the added kinds estimated anew)
    /// when the gap after is above the gap threshold: `explained` is judged against
    /// 1.1 times their largest gap after (at most twice the noise floor), the spread
    /// that estimating the effects on half the blocks leaves when the spec after is
    /// right; 0: against the gap threshold.
    #[arg(long, default_value_t = crate::diagnosis::EXPLAIN_REPLICAS, value_name = "N")]
    pub explain_replicas: usize,
    /// The longest channel diagnosed at its own rate: a longer one is averaged over
    /// blocks of K consecutive samples (the least K that leaves N or fewer) and
    /// diagnosed at the rate over K, in bounded memory; the output path (filter,
    /// resolution, saturation) and outliers are then diagnosed on the log's first
    /// samples at its own rate (--excerpt-samples; contracts.md section 3,
    /// `averaged_by`, `per_sample`); 0: never average.
    #[arg(long, default_value_t = crate::diagnosis::averaged::MAX_SAMPLES, value_name = "N")]
    pub max_samples: usize,
    /// Of a log averaged (--max-samples): its first N samples (at most --max-samples)
    /// are diagnosed at its own rate for the output path and outliers, against the spec
    /// after the averaged diagnosis (contracts.md section 3, `per_sample`); 0: not
    /// diagnosed.
    #[arg(long, default_value_t = crate::diagnosis::averaged::EXCERPT_SAMPLES, value_name = "N")]
    pub excerpt_samples: usize,
    /// Output folder: gap_features/gap_regions/gap_effects.parquet, spec_after.toml, report.svg.
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// The JSON object of contracts.md section 3 on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: GapArgs, progress: &Progress) -> Result<()> {
    let started = Instant::now();
    if let Some(dir) = &a.output {
        // before the work: an OUTDIR that is a file is a usage error
        crate::output::OutputSet::check(dir)?;
    }
    let spec = load_spec(&a.sim)?;
    let store = a.log_args.open(&a.real, progress)?;
    let job = GapJob {
        log: a.real.clone(),
        spec_path: a.sim.clone(),
        spec,
        channels: vec![a.channel.clone()],
        temperature: None,
        params: GapParams {
            train_fraction: a.train_fraction,
            replicas: a.replicas,
            n_blocks: a.blocks,
            seed: a.seed,
            max_added: a.max_effects,
            reestimate: a.reestimate,
            screen: !a.no_screen,
            joint_pairs: !a.no_joint_pairs,
            keep_events: a.keep_events,
            explain_replicas: a.explain_replicas,
            max_samples: a.max_samples,
            excerpt_samples: a.excerpt_samples,
            ..GapParams::default()
        },
    };
    let real = job.real_log(&store, &a.channel)?;
    // a bar on a terminal (stderr, not with --quiet): the search's round, the candidate
    let pb = progress.count_bar("gap", 1);
    let d = diagnose_with_progress(&real, &job.spec, &job.params, &pb);
    pb.finish_and_clear();
    let d = d?;
    let mut json = report::to_json(&d);
    if let Some(dir) = &a.output {
        let files = job.write(dir, std::slice::from_ref(&d))?;
        json["outputs"] = serde_json::json!(files);
    }
    let per_sample = d.per_sample.as_deref().map_or(String::new(), |p| {
        format!(
            "; the per-sample part {:.3} -> {:.3} (significant above {:.3})",
            p.gap_before, p.gap_after, p.gap_threshold
        )
    });
    eprintln!(
        "farma gap {}: gap {:.3} -> {:.3} on the withheld part (noise floor {:.3}, significant above {:.3}){per_sample}; {:.1} s",
        d.channel,
        d.gap_before,
        d.gap_after,
        d.noise_floor,
        d.gap_threshold,
        started.elapsed().as_secs_f64()
    );
    if a.json {
        outln!("{json}");
    } else {
        out!("{}", text(&d));
    }
    Ok(())
}

fn text(d: &crate::diagnosis::Diagnosis) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "channel {}: gap {:.3} before, {:.3} after (noise floor {:.3}, significant above {:.3})",
        d.channel, d.gap_before, d.gap_after, d.noise_floor, d.gap_threshold
    );
    for e in &d.events_excluded {
        let _ = writeln!(
            s,
            "test-stand event excluded: {:.2} .. {:.2} s, {:.0} sd on {}, seen on {}",
            e.start_s,
            e.end_s,
            e.peak_sd,
            d.channel,
            e.channels.join(", ")
        );
    }
    let _ = writeln!(
        s,
        "\nwhere the real log leaves the simulations' band (withheld part of fold 1 or 2):"
    );
    if d.where_before.is_empty() {
        let _ = writeln!(s, "  nowhere");
    }
    for r in d.where_before.iter().take(12) {
        let range = if r.is_whole_part() {
            format!("{:^39}", "(whole withheld part)")
        } else {
            format!("{:>12.4e} .. {:<12.4e} {:<8}", r.lo, r.hi, r.unit)
        };
        let _ = writeln!(
            s,
            "  fold {} {:<13} {:<30} {range} excess {:>7.1} sd",
            r.fold,
            r.statistic.as_str(),
            r.feature,
            r.excess
        );
    }
    let _ = writeln!(
        s,
        "\ncandidate effects, by shrink of the withheld-part gap:"
    );
    for e in &d.effects {
        let _ = writeln!(
            s,
            "  {:<34} shrink {:>7.1} %  gap {:>9.3}  {}",
            e.kind,
            100.0 * e.shrink,
            e.gap_after,
            e.params
        );
    }
    for j in &d.joint_pairs {
        let _ = writeln!(
            s,
            "  pair {:<29} gap {:>9.3}  {}: {}",
            format!("{} + {}", j.kinds[0], j.kinds[1]),
            j.gap_after,
            if j.added { "added" } else { "not added" },
            j.reason
        );
    }
    let _ = writeln!(
        s,
        "\nadded: {}",
        if d.all_added().is_empty() {
            "nothing".to_string()
        } else {
            d.all_added()
                .iter()
                .map(|(part, e)| match *part {
                    "per_sample" => format!("{} (per-sample part)", e.kind),
                    _ => e.kind.clone(),
                })
                .collect::<Vec<_>>()
                .join(", ")
        }
    );
    if d.per_sample.is_some() {
        let _ = writeln!(
            s,
            "verdict of both parts: {}, {}",
            if d.significant {
                "significant"
            } else {
                "not significant"
            },
            if d.explained {
                "explained"
            } else {
                "not explained"
            }
        );
    }
    for n in &d.notes {
        let _ = writeln!(s, "note: {n}");
    }
    if let Some(p) = &d.per_sample {
        let _ = writeln!(
            s,
            "\nthe per-sample part: the log's first {} samples at its own rate, against the spec after the averaged diagnosis\n",
            p.blocks.n
        );
        s += &text(p);
    }
    s
}
