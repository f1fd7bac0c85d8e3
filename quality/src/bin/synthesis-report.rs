//! `synthesis-report`: order-independent synthesis (Wei & Levoy 2002) judged on real samples,
//! in its two search modes, beside the chaos mosaic and a plain tiling of the same exemplar.
//!
//! ```text
//! cargo run --release -p vtex-quality --bin synthesis-report -- [options] <sample files…> --out <dir>
//!   --size N          side of the square output compared, from the texture's origin (256)
//!   --exemplar N      side of the exemplar every method gets (64)
//!   --seed N          noise and block sequence seed (1)
//!   --structured A,B  samples whose structure pixel-based synthesis breaks (the paper's §6):
//!                     reported, not held to the targets (default: skimage-brick)
//!   --embark BIN      also run Embark's texture-synthesis CLI (crate texture-synthesis-cli) on
//!                     each exemplar, on one thread (its only deterministic setting), as an
//!                     offline baseline
//!   --served LABEL=JSON  a served configuration: JSON parameters added to the served mode's
//!                     (repeatable; the first is the one the summary and the targets use;
//!                     default `k-coherence={}`, the model's defaults)
//! ```
//! Samples are GIMP patterns (`.pat`), PNG photos, or `samples:lichen` and `samples:pebbles`, the
//! project's generated samples (the demos'). A photo is prepared as in
//! `vtex_quality::sample`; a pattern is centre-cropped to the exemplar side (a crop does not
//! tile, so every method treats the exemplar as not tileable). For each sample it writes
//! `<name>-fig5.png` (exemplar | exhaustive | k-coherence | chaos mosaic | plain tiling, the
//! paper's Fig. 5 with the served mode and two baselines added) and a section of `report.md`.
//!
//! A `methods` table sets every method beside the others over the stochastic samples, with the
//! lattice share of the order-independent modes (`vtex_quality::lattice`: how many sources are
//! congruent to their pixel modulo 2, 4, 8, as a multiple of chance).
//!
//! Targets on stochastic samples (not `--structured`): patch SW of the served (k-coherence)
//! mode at most the exhaustive mode's, contrast ratio 0.9–1.1, long-range repetition < 0.2.

#![forbid(unsafe_code)]

use serde_json::json;
use std::{collections::BTreeSet, path::PathBuf, process::ExitCode, time::Instant};
use vtex_quality::{
    gimp_pattern,
    lattice::{lattice_shares, LatticeShare},
    patch_sw::SwParams,
    report::{comparison_table, measure, side_by_side, Metrics, TARGET_CONTRAST, TARGET_REPETITION},
    sample::{name_of, prepare_photo},
    seam::Mask,
};
use vtex_synth::{
    models::{self, chaos_mosaic, order_independent, Inputs},
    pixels::decode_png,
    texture::render_image,
    Region, Result, Rgba8Image,
};

struct Options {
    files: Vec<PathBuf>,
    out: PathBuf,
    size: u32,
    exemplar: u32,
    seed: u64,
    structured: BTreeSet<String>,
    embark: Option<PathBuf>,
    served: Vec<(String, serde_json::Value)>,
}

fn parse_args() -> std::result::Result<Options, String> {
    let mut o = Options {
        files: Vec::new(),
        out: PathBuf::new(),
        size: 256,
        exemplar: 64,
        seed: 1,
        structured: BTreeSet::from(["skimage-brick".to_string()]),
        embark: None,
        served: Vec::new(),
    };
    let mut out = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| args.next().ok_or_else(|| format!("{name} needs a value"));
        let number = |name: &str, v: String| v.parse::<u64>().map_err(|_| format!("{name}: `{v}` is not a number"));
        match a.as_str() {
            "--out" => out = Some(PathBuf::from(value("--out")?)),
            "--size" => o.size = number("--size", value("--size")?)?.clamp(64, 2048) as u32,
            "--exemplar" => o.exemplar = number("--exemplar", value("--exemplar")?)?.clamp(32, 256) as u32,
            "--seed" => o.seed = number("--seed", value("--seed")?)?,
            "--structured" => {
                o.structured = value("--structured")?.split(',').filter(|s| !s.is_empty()).map(String::from).collect()
            }
            "--embark" => o.embark = Some(PathBuf::from(value("--embark")?)),
            "--served" => {
                let v = value("--served")?;
                let (label, params) = v.split_once('=').ok_or_else(|| format!("--served {v}: not LABEL=JSON"))?;
                let params: serde_json::Value =
                    serde_json::from_str(params).map_err(|e| format!("--served {label}: {e}"))?;
                if !params.is_object() {
                    return Err(format!("--served {label}: not a JSON object"));
                }
                o.served.push((label.to_string(), params));
            }
            "-h" | "--help" => return Err(String::new()),
            f if f.starts_with("--") => return Err(format!("unknown option {f}")),
            f => o.files.push(PathBuf::from(f)),
        }
    }
    o.out = out.ok_or("--out <dir> is required")?;
    if o.served.is_empty() {
        o.served.push(("k-coherence".into(), json!({})));
    }
    if o.files.is_empty() {
        return Err("no sample files given".into());
    }
    Ok(o)
}

/// One exemplar, prepared from a sample file.
struct Sample {
    name: String,
    kind: &'static str,
    image: Rgba8Image,
}

fn load_sample(path: &std::path::Path, side: u32) -> std::result::Result<Sample, String> {
    let file = path.display().to_string();
    // The project's own generated samples, drawn at the exemplar's side (the demos' seeds).
    let generated = match file.as_str() {
        "samples:lichen" => Some(vtex_synth::samples::lichen(side, 21)),
        "samples:pebbles" => Some(vtex_synth::samples::pebbles(side, 9, 22, false)),
        _ => None,
    };
    if let Some(image) = generated {
        return Ok(Sample { name: file.replace(':', "-"), kind: "generated", image });
    }
    let bytes = std::fs::read(path).map_err(|e| format!("{file}: {e}"))?;
    let name = name_of(path);
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let (kind, image) = match ext.as_str() {
        "pat" => {
            let p = gimp_pattern::parse(&file, &bytes).map_err(|e| e.to_string())?.image;
            if p.width < side || p.height < side {
                return Err(format!("{file}: {}×{} is smaller than the {side}×{side} exemplar", p.width, p.height));
            }
            ("pattern", p.crop((p.width - side) / 2, (p.height - side) / 2, side, side))
        }
        "png" => {
            let img = decode_png(&file, &bytes).map_err(|e| e.to_string())?;
            ("photo", prepare_photo(&img, side).map_err(|e| format!("{file}: {e}"))?)
        }
        _ => return Err(format!("{file}: not a .pat or .png file")),
    };
    Ok(Sample { name, kind, image })
}

/// One method's output window, its joins and how long it took.
struct Output {
    image: Rgba8Image,
    seams: Mask,
    ms: f64,
    /// Lattice shares of its sources modulo 2, 4, 8, when the method reports its sources.
    lattice: Option<Vec<LatticeShare>>,
}

/// The lattice shares of a window at the origin whose pixel (x, y) copies `source(x, y)`.
fn lattice_of(size: u32, source: impl Fn(u32, u32) -> (u32, u32)) -> Vec<LatticeShare> {
    let sources: Vec<(u32, u32)> =
        (0..size).flat_map(|y| (0..size).map(move |x| (x, y))).map(|(x, y)| source(x, y)).collect();
    lattice_shares(0, 0, size, &sources, 3).expect("a square window")
}

fn inputs(sample: &Sample) -> Inputs {
    Inputs::from([("sample".to_string(), sample.image.to_png())])
}

/// The `size × size` window at the origin of a chaos mosaic made with `extra` params.
fn chaos(sample: &Sample, o: &Options, extra: serde_json::Value, grid_seams: bool) -> Result<Output> {
    let (w, h) = (sample.image.width, sample.image.height);
    let mut params = json!({"tiles_x": o.size.div_ceil(w), "tiles_y": o.size.div_ceil(h), "seed": o.seed});
    params.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
    let bundle = models::create(chaos_mosaic::MODEL, &sample.name, &params, &inputs(sample))?;
    let started = Instant::now();
    let image = render_image(&*models::load(&bundle)?, &Region::new(0, 0, 0, o.size, o.size))?;
    let ms = started.elapsed().as_secs_f64() * 1e3;
    let (seams, lattice) = if grid_seams {
        (Mask::grid(o.size, o.size, w, h, 0, 0), Some(lattice_of(o.size, |x, y| (x % w, y % h))))
    } else {
        (Mask::from_bits(o.size, o.size, chaos_mosaic::load(&bundle)?.seam_mask(0, 0, o.size, o.size))?, None)
    };
    Ok(Output { image, seams, ms, lattice })
}

/// The `size × size` window at the origin of an order-independent texture with `extra`
/// parameters; its joins are where neighbouring pixels were not neighbours in the exemplar.
fn order_independent(sample: &Sample, o: &Options, extra: &serde_json::Value) -> Result<Output> {
    let mut params = json!({"seed": o.seed});
    params.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
    let bundle = models::create(order_independent::MODEL, &sample.name, &params, &inputs(sample))?;
    let texture = order_independent::load(&bundle)?;
    let region = Region::new(0, 0, 0, o.size, o.size);
    let started = Instant::now();
    let image = render_image(&texture, &region)?;
    let ms = started.elapsed().as_secs_f64() * 1e3;
    let sources = texture.sources(0, 0, o.size, o.size);
    let source = |x: u32, y: u32| sources[(y * o.size + x) as usize];
    let seams = Mask::from_sources(o.size, o.size, source);
    Ok(Output { image, seams, ms, lattice: Some(lattice_of(o.size, source)) })
}

/// Embark's texture-synthesis, run as its CLI on the exemplar: an `size × size` output whose
/// joins it does not report (its seam ratio is left out).
fn embark(bin: &std::path::Path, sample: &Sample, o: &Options) -> std::result::Result<Output, String> {
    let dir = o.out.join("embark");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (input, output) = (dir.join(format!("{}-in.png", sample.name)), dir.join(format!("{}-out.png", sample.name)));
    std::fs::write(&input, sample.image.to_png()).map_err(|e| format!("{}: {e}", input.display()))?;
    let started = Instant::now();
    let status = std::process::Command::new(bin)
        .args(["--out-size", &o.size.to_string(), "--seed", &o.seed.to_string(), "--threads", "1", "--no-progress"])
        .arg("--out")
        .arg(&output)
        .arg("generate")
        .arg(&input)
        .status()
        .map_err(|e| format!("{}: {e}", bin.display()))?;
    let ms = started.elapsed().as_secs_f64() * 1e3;
    if !status.success() {
        return Err(format!("{}: {status}", bin.display()));
    }
    let bytes = std::fs::read(&output).map_err(|e| format!("{}: {e}", output.display()))?;
    let image = decode_png("embark output", &bytes).map_err(|e| e.to_string())?;
    Ok(Output { seams: Mask::grid(image.width, image.height, o.exemplar, o.exemplar, 0, 0), image, ms, lattice: None })
}

/// One method's output judged: its metrics, time and lattice shares.
struct Judgement {
    metrics: Metrics,
    ms: f64,
    lattice: Option<Vec<LatticeShare>>,
}

struct Judged {
    sample: Sample,
    stochastic: bool,
    exhaustive: (Metrics, f64),
    /// The first served configuration.
    served: (Metrics, f64),
    chaos: Metrics,
    tiling: Metrics,
    embark: Option<(Metrics, f64)>,
    /// Every method by label, in the `methods` table's order.
    methods: Vec<(String, Judgement)>,
}

impl Judged {
    /// The targets, held on stochastic samples only.
    fn targets(&self) -> Vec<(&'static str, bool)> {
        let s = &self.served.0;
        vec![
            ("SW ≤ exhaustive", s.patch_sw.mean <= self.exhaustive.0.patch_sw.mean),
            ("contrast", (TARGET_CONTRAST.0..=TARGET_CONTRAST.1).contains(&s.contrast)),
            ("repetition", s.repetition.value < TARGET_REPETITION),
        ]
    }

    fn verdict(&self) -> String {
        let missed: Vec<&str> = self.targets().into_iter().filter(|t| !t.1).map(|t| t.0).collect();
        match (self.stochastic, missed.is_empty()) {
            (false, _) => "reported (structured)".into(),
            (true, true) => "met".into(),
            (true, false) => format!("missed: {}", missed.join(", ")),
        }
    }
}

fn judge(sample: Sample, o: &Options) -> std::result::Result<Judged, String> {
    let err = |e: vtex_synth::Error| format!("{}: {e}", sample.name);
    let sw = SwParams::default();
    let exhaustive = order_independent(&sample, o, &json!({"search": "exhaustive"})).map_err(err)?;
    let served: Vec<Output> =
        o.served.iter().map(|(_, p)| order_independent(&sample, o, p)).collect::<Result<_>>().map_err(err)?;
    let mosaic = chaos(&sample, o, json!({}), false).map_err(err)?;
    let tiling = chaos(&sample, o, json!({"iterations": 0, "filter_width": 0}), true).map_err(err)?;
    let embarked = o.embark.as_deref().map(|bin| embark(bin, &sample, o)).transpose()?;
    let mut panels = vec![&sample.image, &exhaustive.image];
    panels.extend(served.iter().map(|s| &s.image));
    panels.extend([&mosaic.image, &tiling.image]);
    panels.extend(embarked.as_ref().map(|e| &e.image));
    let fig = side_by_side(&panels);
    let file = format!("{}-fig5.png", sample.name);
    std::fs::write(o.out.join(&file), fig.to_png()).map_err(|e| format!("{file}: {e}"))?;
    let m = |out: &Output| measure(&out.image, &sample.image, &out.seams, &sw).map_err(err);
    let judge =
        |out: &Output| Ok::<_, String>(Judgement { metrics: m(out)?, ms: out.ms, lattice: out.lattice.clone() });
    let mut methods = vec![("exhaustive".to_string(), judge(&exhaustive)?)];
    for ((label, _), out) in o.served.iter().zip(&served) {
        methods.push((label.clone(), judge(out)?));
    }
    methods.push(("chaos mosaic".into(), judge(&mosaic)?));
    methods.push(("plain tiling".into(), judge(&tiling)?));
    if let Some(e) = &embarked {
        methods.push(("Embark".into(), judge(e)?));
    }
    Ok(Judged {
        stochastic: !o.structured.contains(&sample.name),
        exhaustive: (m(&exhaustive)?, exhaustive.ms),
        served: (m(&served[0])?, served[0].ms),
        methods,
        chaos: m(&mosaic)?,
        tiling: m(&tiling)?,
        embark: embarked.as_ref().map(|e| Ok::<_, String>((m(e)?, e.ms))).transpose()?,
        sample,
    })
}

/// Every method over the samples `all`: contrast range and how many are in the target, the
/// worst repetition and seam ratio, the mean histogram distance, lattice share (mean, as a
/// multiple of chance, modulo 2 / 4 / 8), patch SW and time.
fn methods(all: &[&Judged]) -> String {
    let mut s = String::from(
        "| method | contrast: min–max (in 0.9–1.1) | repetition: max | seam ratio: mean / max | histogram W1: mean | lattice ×chance mod 2 / 4 / 8 | patch SW: mean | ms: mean |\n\
         |---|---|---:|---:|---:|---|---:|---:|\n",
    );
    let Some(first) = all.first() else { return s };
    let n = all.len() as f64;
    for (i, (label, _)) in first.methods.iter().enumerate() {
        let of = |f: &dyn Fn(&Judgement) -> f64| all.iter().map(|j| f(&j.methods[i].1)).collect::<Vec<f64>>();
        let contrast = of(&|j| j.metrics.contrast);
        let inside = contrast.iter().filter(|c| (TARGET_CONTRAST.0..=TARGET_CONTRAST.1).contains(*c)).count();
        let max = |v: &[f64]| v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let min = |v: &[f64]| v.iter().cloned().fold(f64::INFINITY, f64::min);
        let mean = |v: &[f64]| v.iter().sum::<f64>() / n;
        let seam = of(&|j| j.metrics.seam_ratio);
        let lattice = if all.iter().all(|j| j.methods[i].1.lattice.is_some()) {
            (0..3)
                .map(|b| format!("{:.2}", mean(&of(&|j| j.lattice.as_ref().unwrap()[b].excess()))))
                .collect::<Vec<_>>()
                .join(" / ")
        } else {
            "—".into()
        };
        s += &format!(
            "| {label} | {:.2}–{:.2} ({inside}/{}) | {:.3} | {:.2} / {:.2} | {:.2} | {lattice} | {:.2} | {:.0} |\n",
            min(&contrast),
            max(&contrast),
            all.len(),
            max(&of(&|j| j.metrics.repetition.value)),
            mean(&seam),
            max(&seam),
            mean(&of(&|j| j.metrics.histogram_w1_mean())),
            mean(&of(&|j| j.metrics.patch_sw.mean)),
            mean(&of(&|j| j.ms)),
        );
    }
    s
}

fn summary(all: &[Judged]) -> String {
    let mut s = String::from(
        "| sample | kind | patch SW: exhaustive / k-coherence / chaos / tiling | served ÷ exhaustive | contrast: exhaustive / k-coherence | repetition: k-coherence / tiling | seam ratio k-coherence | ms: exhaustive / k-coherence | Embark: SW / ms | targets |\n\
         |---|---|---:|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for j in all {
        let (e, k) = (&j.exhaustive.0, &j.served.0);
        s += &format!(
            "| {} | {} | {:.2} / **{:.2}** / {:.2} / {:.2} | {:.2} | {:.3} / **{:.3}** | **{:.3}** / {:.3} | {:.2} | {:.0} / {:.0} | {} | {} |\n",
            j.sample.name,
            j.sample.kind,
            e.patch_sw.mean,
            k.patch_sw.mean,
            j.chaos.patch_sw.mean,
            j.tiling.patch_sw.mean,
            k.patch_sw.mean / e.patch_sw.mean,
            e.contrast,
            k.contrast,
            k.repetition.value,
            j.tiling.repetition.value,
            k.seam_ratio,
            j.exhaustive.1,
            j.served.1,
            j.embark.as_ref().map_or("—".into(), |(m, ms)| format!("{:.2} / {ms:.0}", m.patch_sw.mean)),
            j.verdict(),
        );
    }
    s
}

fn run(o: &Options) -> std::result::Result<usize, String> {
    std::fs::create_dir_all(&o.out).map_err(|e| format!("{}: {e}", o.out.display()))?;
    let mut names = BTreeSet::new();
    let mut all = Vec::new();
    let mut skipped = Vec::new();
    for path in &o.files {
        let judged = load_sample(path, o.exemplar).and_then(|sample| {
            if !names.insert(sample.name.clone()) {
                return Err(format!("{}: a second sample named `{}`; rename one", path.display(), sample.name));
            }
            judge(sample, o)
        });
        match judged {
            Ok(j) => {
                for (label, m) in &j.methods {
                    let lattice = m.lattice.as_ref().map_or("—".into(), |l| {
                        l.iter().map(|s| format!("{:.2}", s.excess())).collect::<Vec<_>>().join("/")
                    });
                    eprintln!(
                        "  {:<20} {:<16} contrast {:.3}  repetition {:.3}  seams {:.2}  W1 {:.2}  lattice {lattice}  SW {:.2}  {:.0} ms",
                        j.sample.name,
                        label,
                        m.metrics.contrast,
                        m.metrics.repetition.value,
                        m.metrics.seam_ratio,
                        m.metrics.histogram_w1_mean(),
                        m.metrics.patch_sw.mean,
                        m.ms
                    );
                }
                eprintln!(
                    "{:<20} SW exhaustive {:.2}  k-coherence {:.2}  contrast {:.3}  repetition {:.3}  {}",
                    j.sample.name,
                    j.exhaustive.0.patch_sw.mean,
                    j.served.0.patch_sw.mean,
                    j.served.0.contrast,
                    j.served.0.repetition.value,
                    j.verdict()
                );
                all.push(j);
            }
            Err(e) => {
                eprintln!("skipped: {e}");
                skipped.push(e);
            }
        }
    }
    let gated: Vec<&Judged> = all.iter().filter(|j| j.stochastic).collect();
    let missed = gated.iter().filter(|j| j.targets().iter().any(|t| !t.1)).count();
    let mut md = format!(
        "# Order-independent synthesis on real samples\n\n\
         Output: the {s}×{s} window at the origin of each texture (level 0), from a {e}×{e} exemplar \
         (photos halved while their shorter side is ≥ {e4} px, then centre-cropped; patterns centre-cropped). \
         Order-independent: the model's defaults (4 levels, 3 generations, circle-5 + 3×3 parent), seed {seed}, \
         search exhaustive (the paper's Table 1) and k-coherence (served). Chaos mosaic: the paper's defaults. \
         Patch SW: 5×5 patches, 3 scales, 32 directions. Structured samples are reported, not held to the targets. \
         Targets missed on {missed} of {n} stochastic samples.\n\n## Methods over the stochastic samples\n\n{}\n\
         Served configurations: {}.\n\n## Summary\n\n{}\n{}",
        methods(&gated),
        o.served.iter().map(|(l, p)| format!("`{l}` = `{p}`")).collect::<Vec<_>>().join(", "),
        summary(&all),
        if skipped.is_empty() {
            String::new()
        } else {
            format!("Skipped:\n\n{}\n", skipped.iter().map(|e| format!("- {e}\n")).collect::<String>())
        },
        s = o.size,
        e = o.exemplar,
        e4 = 4 * o.exemplar,
        seed = o.seed,
        n = gated.len(),
    );
    for j in &all {
        md += &format!(
            "## {}\n\n{} {}: exemplar | exhaustive | k-coherence | chaos mosaic | plain tiling{}.\n\n![{} compared]({}-fig5.png)\n\n",
            j.sample.name,
            j.sample.kind,
            j.sample.name,
            if j.embark.is_some() { " | Embark (its seam ratio is not known)" } else { "" },
            j.sample.name,
            j.sample.name
        );
        let mut cols = vec![
            ("exhaustive", &j.exhaustive.0),
            ("k-coherence", &j.served.0),
            ("chaos mosaic", &j.chaos),
            ("plain tiling", &j.tiling),
        ];
        cols.extend(j.embark.as_ref().map(|(m, _)| ("Embark", m)));
        md += &comparison_table(&cols);
        md += "\n";
    }
    let path = o.out.join("report.md");
    std::fs::write(&path, md).map_err(|e| format!("{}: {e}", path.display()))?;
    println!("{}\n{}", methods(&gated), summary(&all));
    eprintln!("wrote {} ({missed} of {} stochastic samples miss a target)", path.display(), gated.len());
    if all.is_empty() {
        return Err("no sample could be judged".into());
    }
    Ok(missed)
}

fn main() -> ExitCode {
    let o = match parse_args() {
        Ok(o) => o,
        Err(e) => {
            if !e.is_empty() {
                eprintln!("synthesis-report: {e}");
            }
            eprintln!("usage: synthesis-report [--size N] [--exemplar N] [--seed N] [--structured A,B] <samples (.pat, .png)…> --out <dir>");
            return ExitCode::from(2);
        }
    };
    match run(&o) {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("synthesis-report: {e}");
            ExitCode::FAILURE
        }
    }
}
