//! `vtex-fuzz <target> --seconds N [--seed S]`, or `--replay FILE` to rerun a saved input.

use clap::Parser;
use std::process::ExitCode;
use std::time::Duration;
use vtex_fuzz::{alloc::Counting, harness, targets};

#[global_allocator]
static ALLOC: Counting = Counting;

#[derive(Parser)]
#[command(about = "Fuzz one of vtex's parsers; a failing input is written to fuzz/crashes/")]
struct Args {
    /// bundle, manifest-cascade, manifest-chaos-mosaic, manifest-lcm, manifest-patterns, png,
    /// query, or `list`.
    target: String,
    /// How long to fuzz.
    #[arg(long, default_value_t = 60.0)]
    seconds: f64,
    /// Seed of the mutations (a run is repeatable up to timing).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Run one saved input instead of fuzzing.
    #[arg(long)]
    replay: Option<std::path::PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    if args.target == "list" {
        targets::TARGETS.iter().for_each(|t| println!("{}", t.name()));
        return ExitCode::SUCCESS;
    }
    let Some(target) = targets::by_name(&args.target) else {
        let names: Vec<_> = targets::TARGETS.iter().map(|t| t.name()).collect();
        eprintln!("unknown target `{}`; targets: {}", args.target, names.join(", "));
        return ExitCode::from(2);
    };
    if let Some(path) = args.replay {
        let input = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("{}: {e}", path.display());
                return ExitCode::from(2);
            }
        };
        let accepted = harness::replay(target, &input);
        println!(
            "{}: {} ran within its bounds ({})",
            target.name(),
            path.display(),
            ["rejected", "accepted"][accepted as usize]
        );
        return ExitCode::SUCCESS;
    }
    let stats = harness::fuzz(target, Duration::from_secs_f64(args.seconds), args.seed);
    println!(
        "{}: seed {}: {stats}; no panic, no allocation over the bounds, no input over the time bound",
        target.name(),
        args.seed
    );
    ExitCode::SUCCESS
}
