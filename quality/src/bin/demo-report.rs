//! `demo-report`: every demo of every model in one table — long-range repetition, contrast
//! against its sample (for the models made from one) and mip coherence.
//!
//! ```text
//! cargo run --release -p vtex-quality --bin demo-report -- [--side N] [--out FILE]
//!   --side N    side of the level-0 window at the origin that is measured (1024)
//!   --out FILE  also write the table there (markdown)
//! ```
//! Repetition is the largest autocorrelation of the window's luminance at lags beyond the
//! sample's size (models made from a sample) or beyond 64 pixels (the others), with its lag.
//! Mip coherence is the worst PSNR of levels 1–6 of the window against its exact box chain,
//! with point sampling (the aliasing baseline) at that level beside it. A texture smaller than
//! the window is measured whole, at the largest power-of-two side it holds.

#![forbid(unsafe_code)]

use std::fmt::Write as _;
use std::process::ExitCode;
use vtex_quality::contrast::contrast_ratio;
use vtex_quality::mip::psnr_by_level;
use vtex_quality::repetition::repetition;
use vtex_synth::bundle::Bundle;
use vtex_synth::models::{self, input_image};
use vtex_synth::texture::render_image;
use vtex_synth::{Region, Result};

const LEVELS: u32 = 6;
/// The repetition's exclusion for textures made without a sample.
const NO_SAMPLE_EXCLUSION: u32 = 64;

struct Row {
    model: String,
    name: String,
    side: u32,
    repetition: String,
    contrast: String,
    mip: String,
}

fn measure(bundle: &Bundle, max_side: u32) -> Result<Row> {
    let model = models::get(&bundle.manifest.model)?;
    let texture = models::load(bundle)?;
    let fits = texture.width().min(texture.height()).min(max_side as u64);
    let side = 1u32 << (63 - fits.leading_zeros()).min(31);
    let window = render_image(texture.as_ref(), &Region::new(0, 0, 0, side, side))?;
    let sample = model.inputs_of(bundle).ok().and_then(|inputs| input_image(&inputs, "sample").ok());
    let exclusion = sample.as_ref().map_or((NO_SAMPLE_EXCLUSION, NO_SAMPLE_EXCLUSION), |s| (s.width, s.height));
    let repetition = match repetition(&window, exclusion.0, exclusion.1) {
        Ok(r) => format!("{:.3} at ({}, {})", r.value, r.dx, r.dy),
        Err(e) => format!("— ({e})"),
    };
    let contrast = match &sample {
        Some(s) => format!("{:.3}", contrast_ratio(&window, s)?),
        None => "—".to_string(),
    };
    let levels = LEVELS.min(side.trailing_zeros());
    let worst = psnr_by_level(texture.as_ref(), side, levels)?
        .into_iter()
        .min_by(|a, b| a.served_db.total_cmp(&b.served_db))
        .map_or("—".to_string(), |m| match m.served_db.is_finite() {
            true => format!("{:.1} dB at L{} (point {:.1})", m.served_db, m.level, m.point_db),
            false => format!("exact at levels 1–{levels}"),
        });
    Ok(Row {
        model: bundle.manifest.model.clone(),
        name: bundle.manifest.name.clone(),
        side,
        repetition,
        contrast,
        mip: worst,
    })
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut side = 1024u32;
    let mut out = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match (a.as_str(), it.next()) {
            ("--side", Some(v)) => match v.parse::<u32>() {
                Ok(n) if n.is_power_of_two() && n >= 64 => side = n,
                _ => return usage(&format!("--side takes a power of two ≥ 64, not `{v}`")),
            },
            ("--out", Some(v)) => out = Some(v.clone()),
            _ => return usage(&format!("unknown argument `{a}`")),
        }
    }
    let mut table = String::from(
        "| model | demo | window | repetition (lag) | contrast | worst mip PSNR, levels 1–6 |\n|---|---|---:|---|---:|---|\n",
    );
    let mut failed = false;
    for bundle in models::demos() {
        match measure(&bundle, side) {
            Ok(r) => {
                writeln!(
                    table,
                    "| {} | {} | {}² | {} | {} | {} |",
                    r.model, r.name, r.side, r.repetition, r.contrast, r.mip
                )
                .unwrap();
            }
            Err(e) => {
                eprintln!("{}: {e}", bundle.manifest.name);
                failed = true;
            }
        }
    }
    print!("{table}");
    if let Some(path) = out {
        if let Err(e) = std::fs::write(&path, &table) {
            eprintln!("{path}: {e}");
            return ExitCode::FAILURE;
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

fn usage(problem: &str) -> ExitCode {
    eprintln!("demo-report: {problem}\nusage: demo-report [--side N] [--out FILE]");
    ExitCode::from(2)
}
