//! `quality-report`: judges the chaos mosaic against a plain tiling on real samples.
//!
//! ```text
//! cargo run --release -p vtex-quality --bin quality-report -- [options] <sample files…> --out <dir>
//!   --size N         side of the square output compared, from the texture's origin (1024)
//!   --photo-side N   side a photo is reduced and centre-cropped to (128)
//!   --iterations N   cat map iterations of the chaos mosaic (10)
//!   --seed N         block sequence seed (1)
//!   --c-lambda X     smallest block area / sample area (0.5, the paper's)
//!   --c-mu X         largest block area / sample area (0.75, the paper's)
//!   --blocks-per-tile N  random blocks cut from each tile (1, the paper's)
//! ```
//! Samples are GIMP patterns (`.pat`, used at their own size) or PNG photos (prepared as in
//! `vtex_quality::sample`). For each sample it writes `<name>-sample.png`,
//! `<name>-side-by-side.png` (plain tiling | chaos mosaic) and a section of `report.md`.

#![forbid(unsafe_code)]

use serde_json::json;
use std::{collections::BTreeSet, path::PathBuf, process::ExitCode, time::Instant};
use vtex_quality::{
    gimp_pattern,
    patch_sw::SwParams,
    repetition::repetition,
    report::{comparison_table, measure, side_by_side, Metrics},
    sample::{name_of, prepare_pattern, prepare_photo, PHOTO_SIDE},
    seam::Mask,
};
use vtex_synth::{
    models::{self, chaos_mosaic, Inputs},
    pixels::decode_png,
    texture::render_image,
    Region, Result, Rgba8Image,
};

struct Options {
    files: Vec<PathBuf>,
    out: PathBuf,
    size: u32,
    photo_side: u32,
    iterations: u32,
    seed: u64,
    c_lambda: f64,
    c_mu: f64,
    blocks_per_tile: u32,
}

fn parse_args() -> std::result::Result<Options, String> {
    let mut o = Options {
        files: Vec::new(),
        out: PathBuf::new(),
        size: 1024,
        photo_side: PHOTO_SIDE,
        iterations: 10,
        seed: 1,
        c_lambda: 0.5,
        c_mu: 0.75,
        blocks_per_tile: 1,
    };
    let mut out = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| args.next().ok_or_else(|| format!("{name} needs a value"));
        let number = |name: &str, v: String| v.parse::<u64>().map_err(|_| format!("{name}: `{v}` is not a number"));
        let fraction = |name: &str, v: String| v.parse::<f64>().map_err(|_| format!("{name}: `{v}` is not a number"));
        match a.as_str() {
            "--out" => out = Some(PathBuf::from(value("--out")?)),
            "--size" => o.size = number("--size", value("--size")?)?.clamp(16, 8192) as u32,
            "--photo-side" => o.photo_side = number("--photo-side", value("--photo-side")?)?.clamp(8, 1024) as u32,
            "--iterations" => o.iterations = number("--iterations", value("--iterations")?)?.min(1000) as u32,
            "--seed" => o.seed = number("--seed", value("--seed")?)?,
            "--c-lambda" => o.c_lambda = fraction("--c-lambda", value("--c-lambda")?)?,
            "--c-mu" => o.c_mu = fraction("--c-mu", value("--c-mu")?)?,
            "--blocks-per-tile" => {
                o.blocks_per_tile = number("--blocks-per-tile", value("--blocks-per-tile")?)?.clamp(1, 8) as u32
            }
            "-h" | "--help" => return Err(String::new()),
            f if f.starts_with("--") => return Err(format!("unknown option {f}")),
            f => o.files.push(PathBuf::from(f)),
        }
    }
    o.out = out.ok_or("--out <dir> is required")?;
    if o.files.is_empty() {
        return Err("no sample files given".into());
    }
    Ok(o)
}

/// One prepared sample.
struct Sample {
    name: String,
    kind: &'static str,
    source_size: (u32, u32),
    image: Rgba8Image,
}

fn load_sample(path: &std::path::Path, photo_side: u32) -> std::result::Result<Sample, String> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| format!("{file}: {e}"))?;
    let name = name_of(path);
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let (kind, source, image) = match ext.as_str() {
        "pat" => {
            let p = gimp_pattern::parse(&file, &bytes).map_err(|e| e.to_string())?;
            let image = prepare_pattern(&p.image).map_err(|e| format!("{file}: {e}"))?;
            ("pattern", p.image, image)
        }
        "png" => {
            let img = decode_png(&file, &bytes).map_err(|e| e.to_string())?;
            let image = prepare_photo(&img, photo_side).map_err(|e| format!("{file}: {e}"))?;
            ("photo", img, image)
        }
        _ => return Err(format!("{file}: not a .pat or .png file")),
    };
    Ok(Sample { name, kind, source_size: (source.width, source.height), image })
}

/// An output of one model configuration, with the places where it joins copies.
struct Output {
    image: Rgba8Image,
    seams: Mask,
    /// Fraction of the window no block covers: the plain tiling shows through there.
    uncovered: f64,
}

/// Renders the `size × size` window at the origin of a chaos mosaic made with `extra` params.
fn chaos(sample: &Sample, o: &Options, extra: serde_json::Value, grid_seams: bool) -> Result<Output> {
    let (w, h) = (sample.image.width, sample.image.height);
    let mut params = json!({
        "tiles_x": o.size.div_ceil(w),
        "tiles_y": o.size.div_ceil(h),
        "iterations": o.iterations,
        "seed": o.seed,
        "c_lambda": o.c_lambda,
        "c_mu": o.c_mu,
        "blocks_per_tile": o.blocks_per_tile,
    });
    params.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
    let inputs = Inputs::from([("sample".to_string(), sample.image.to_png())]);
    let bundle = models::create(chaos_mosaic::MODEL, &sample.name, &params, &inputs)?;
    let texture = models::load(&bundle)?;
    let image = render_image(&*texture, &Region::new(0, 0, 0, o.size, o.size))?;
    let mosaic = chaos_mosaic::load(&bundle)?;
    let seams = if grid_seams {
        Mask::grid(o.size, o.size, w, h, 0, 0)
    } else {
        Mask::from_bits(o.size, o.size, mosaic.seam_mask(0, 0, o.size, o.size))?
    };
    Ok(Output { image, seams, uncovered: uncovered_fraction(&mosaic, o.size) })
}

/// The share of the `size × size` window at the origin that no block covers (blocks wrap
/// around the texture torus). With one block per tile of mean area a·n², about e^(−a) of the
/// tiling stays uncovered, and two pixels one tile apart both show it with probability
/// e^(−2a): the floor of the long-range repetition for the paper's construction.
fn uncovered_fraction(mosaic: &chaos_mosaic::ChaosMosaic, size: u32) -> f64 {
    use vtex_synth::Texture;
    let (tw, th) = (mosaic.width(), mosaic.height());
    let size = size as usize;
    let mut covered = vec![false; size * size];
    for b in mosaic.blocks() {
        for dy in 0..b.h as u64 {
            let y = ((b.t as u64 + dy) % th) as usize;
            if y >= size {
                continue;
            }
            for dx in 0..b.w as u64 {
                let x = ((b.s as u64 + dx) % tw) as usize;
                if x < size {
                    covered[y * size + x] = true;
                }
            }
        }
    }
    covered.iter().filter(|&&c| !c).count() as f64 / covered.len() as f64
}

struct Judged {
    sample: Sample,
    seamless: bool,
    self_repetition: Option<f64>,
    tiling: Metrics,
    filtered_tiling: Option<Metrics>,
    chaos: Metrics,
    uncovered: f64,
}

fn judge(sample: Sample, o: &Options) -> std::result::Result<Judged, String> {
    let err = |e: vtex_synth::Error| format!("{}: {e}", sample.name);
    let sw = SwParams::default();
    let seamless = chaos_mosaic::is_seamless(&sample.image);
    // The plain tiling: no block moved, nothing filtered.
    let tiling = chaos(&sample, o, json!({"iterations": 0, "filter_width": 0}), true).map_err(err)?;
    let mosaic = chaos(&sample, o, json!({}), false).map_err(err)?;
    let dir = &o.out;
    let write = |file: String, img: &Rgba8Image| {
        std::fs::write(dir.join(&file), img.to_png()).map_err(|e| format!("{file}: {e}"))
    };
    write(format!("{}-sample.png", sample.name), &sample.image)?;
    write(format!("{}-side-by-side.png", sample.name), &side_by_side(&[&tiling.image, &mosaic.image]))?;
    let m = |out: &Output| measure(&out.image, &sample.image, &out.seams, &sw).map_err(err);
    // A sample that is not seamless also gets the tiling with its tile edges cross-edge
    // filtered (zero iterations, default filter): what filtering alone achieves.
    let filtered_tiling =
        if seamless { None } else { Some(m(&chaos(&sample, o, json!({"iterations": 0}), false).map_err(err)?)?) };
    let (sw_, sh_) = (sample.image.width, sample.image.height);
    let self_repetition = repetition(&sample.image, (sw_ / 4).max(1), (sh_ / 4).max(1)).ok().map(|r| r.value);
    Ok(Judged {
        seamless,
        self_repetition,
        tiling: m(&tiling)?,
        filtered_tiling,
        chaos: m(&mosaic)?,
        uncovered: mosaic.uncovered,
        sample,
    })
}

fn summary(all: &[Judged]) -> String {
    let mut s = String::from(
        "| sample | kind | source → sample | seamless | sample self-rep. | tiling uncovered | repetition tiling → chaos | chaos r at 1 period | seam ratio tiling → chaos | contrast chaos | hist W1 chaos | patch SW tiling → chaos | targets |\n\
         |---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for j in all {
        let (t, c) = (&j.tiling, &j.chaos);
        s += &format!(
            "| {} | {} | {}×{} → {}×{} | {} | {} | {:.0}% | {:.3} → **{:.3}** | {} | {:.2} → **{:.2}** | **{:.3}** | {:.2} | {:.2} → {:.2} | {} |\n",
            j.sample.name,
            j.sample.kind,
            j.sample.source_size.0,
            j.sample.source_size.1,
            j.sample.image.width,
            j.sample.image.height,
            if j.seamless { "yes" } else { "no" },
            j.self_repetition.map_or("—".into(), |v| format!("{v:.2}")),
            100.0 * j.uncovered,
            t.repetition.value,
            c.repetition.value,
            c.period_r.map(|r| r.map_or("—".into(), |v| format!("{v:.2}"))).join(" / "),
            t.seam_ratio,
            c.seam_ratio,
            c.contrast,
            c.histogram_w1_mean(),
            t.patch_sw.mean,
            c.patch_sw.mean,
            if c.meets_targets() { "met" } else { "missed" },
        );
    }
    s
}

fn run(o: &Options) -> std::result::Result<(), String> {
    std::fs::create_dir_all(&o.out).map_err(|e| format!("{}: {e}", o.out.display()))?;
    let mut names = BTreeSet::new();
    let mut all = Vec::new();
    // A sample the metrics cannot judge (e.g. colour constant, pattern only in alpha) is
    // listed with its reason; the others still get their report.
    let mut skipped = Vec::new();
    for path in &o.files {
        let started = Instant::now();
        let judged = load_sample(path, o.photo_side).and_then(|sample| {
            if !names.insert(sample.name.clone()) {
                return Err(format!("{}: a second sample named `{}`; rename one", path.display(), sample.name));
            }
            judge(sample, o)
        });
        let j = match judged {
            Ok(j) => j,
            Err(e) => {
                eprintln!("skipped: {e}");
                skipped.push(e);
                continue;
            }
        };
        eprintln!(
            "{:<16} repetition {:.3} → {:.3}  seam {:.2} → {:.2}  contrast {:.3}  uncovered {:.0}%  ({:.1} s)",
            j.sample.name,
            j.tiling.repetition.value,
            j.chaos.repetition.value,
            j.tiling.seam_ratio,
            j.chaos.seam_ratio,
            j.chaos.contrast,
            100.0 * j.uncovered,
            started.elapsed().as_secs_f64()
        );
        all.push(j);
    }
    let met = all.iter().filter(|j| j.chaos.meets_targets()).count();
    let mut md = format!(
        "# Quality report: plain tiling vs chaos mosaic\n\n\
         Output: the {s}×{s} window at the origin of each texture (tiles to cover it; level 0). \
         Chaos mosaic: {i} cat map iterations, seed {seed}, c_λ = {cl}, c_μ = {cm}, {bpt} block(s) a tile, \
         3-pixel cross-edge filter. Plain tiling: 0 iterations, no filter. Patterns are used at their own size; photos are \
         halved while their shorter side is ≥ {p4} px, then centre-cropped to {p}×{p}. Patch SW: 5×5 \
         patches, 3 scales, 32 directions. Targets met by the chaos mosaic on {met} of {n} samples.\n\n\
         ## Summary\n\n{}\n{}",
        summary(&all),
        if skipped.is_empty() {
            String::new()
        } else {
            format!("Skipped:\n\n{}\n", skipped.iter().map(|e| format!("- {e}\n")).collect::<String>())
        },
        s = o.size,
        i = o.iterations,
        bpt = o.blocks_per_tile,
        seed = o.seed,
        cl = o.c_lambda,
        cm = o.c_mu,
        p = o.photo_side,
        p4 = 4 * o.photo_side,
        n = all.len(),
    );
    for j in &all {
        md += &format!(
            "## {}\n\n{} {}, {}×{} → {}×{} sample, {}.\n\n![{} side by side]({}-side-by-side.png)\n\n",
            j.sample.name,
            j.sample.kind,
            j.sample.name,
            j.sample.source_size.0,
            j.sample.source_size.1,
            j.sample.image.width,
            j.sample.image.height,
            if j.seamless { "seamless" } else { "not seamless (tile edges are seams)" },
            j.sample.name,
            j.sample.name,
        );
        let mut cols = vec![("plain tiling", &j.tiling)];
        if let Some(f) = &j.filtered_tiling {
            cols.push(("tiling + edge filter", f));
        }
        cols.push(("chaos mosaic", &j.chaos));
        md += &comparison_table(&cols);
        md += "\n";
    }
    let path = o.out.join("report.md");
    std::fs::write(&path, md).map_err(|e| format!("{}: {e}", path.display()))?;
    println!("{}", summary(&all));
    eprintln!("wrote {} ({met} of {} samples meet every target, {} skipped)", path.display(), all.len(), skipped.len());
    if all.is_empty() {
        return Err("no sample could be judged".into());
    }
    Ok(())
}

fn main() -> ExitCode {
    let o = match parse_args() {
        Ok(o) => o,
        Err(e) => {
            if !e.is_empty() {
                eprintln!("quality-report: {e}");
            }
            eprintln!("usage: quality-report [--size N] [--photo-side N] [--iterations N] [--seed N] <samples (.pat, .png)…> --out <dir>");
            return ExitCode::from(2);
        }
    };
    match run(&o) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("quality-report: {e}");
            ExitCode::FAILURE
        }
    }
}
