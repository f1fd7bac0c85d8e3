//! Level 0 of every by-example demo against the answers a texture server could give without
//! synthesizing anything: a flat mean colour and a verbatim tiling of the sample. Each model
//! claims gates (repetition, contrast, seams) that its served level 0 passes; every claimed
//! gate set must reject both trivial answers, so no claim is one a copy or a flat colour also
//! meets. Coarse levels are held the same way by the conformance suite (`synth/tests`).

use vtex_quality::{
    contrast::contrast_ratio,
    repetition::Autocorrelation,
    seam::{seam_ratio, Mask},
};
use vtex_synth::models::{chaos_mosaic, order_independent};
use vtex_synth::pixels::decode_png;
use vtex_synth::{bundle::Bundle, texture::render_image, Region, Rgba8Image};

/// Side of the level-0 window judged, away from the origin.
const SIDE: u32 = 1024;
const ORIGIN: (i64, i64) = (1536, -2048);

/// What a model claims its level 0 keeps: each bound is a gate.
struct Claim {
    model: &'static str,
    /// Largest normalised autocorrelation beyond the sample's size.
    max_repetition: f64,
    /// Luminance σ over the sample's.
    contrast: (f64, f64),
    /// Gradient on the joins over the gradient elsewhere; `None` where not claimed.
    max_seam_ratio: Option<f64>,
}

/// The chaos mosaic claims no seam bound: the paper's 3-pixel cross-edge filter leaves the
/// joins of a low-frequency sample visible (the lichen demo's ratio is about 1.65).
const CLAIMS: [Claim; 2] = [
    Claim { model: chaos_mosaic::MODEL, max_repetition: 0.55, contrast: (0.85, 1.1), max_seam_ratio: None },
    Claim { model: order_independent::MODEL, max_repetition: 0.2, contrast: (0.9, 1.1), max_seam_ratio: Some(1.0) },
];

/// One answer's metrics; `None` where a metric is undefined (no joins, or a luminance without
/// any variation), which no gate accepts.
#[derive(Debug)]
struct Scores {
    repetition: Option<f64>,
    contrast: f64,
    seams: Option<f64>,
}

impl Scores {
    fn of(img: &Rgba8Image, sample: &Rgba8Image, joins: &Mask) -> Scores {
        let repetition =
            Autocorrelation::new(img).and_then(|a| a.max_outside(sample.width, sample.height)).ok().map(|r| r.value);
        Scores {
            repetition,
            contrast: contrast_ratio(img, sample).expect("the sample has contrast"),
            seams: seam_ratio(img, |x, y| joins.get(x, y)).ok(),
        }
    }

    /// The gates of `c` these scores fail.
    fn failed(&self, c: &Claim) -> Vec<&'static str> {
        let mut failed = Vec::new();
        if !self.repetition.is_some_and(|r| r <= c.max_repetition) {
            failed.push("repetition");
        }
        if !(c.contrast.0..=c.contrast.1).contains(&self.contrast) {
            failed.push("contrast");
        }
        if c.max_seam_ratio.is_some_and(|max| !self.seams.is_some_and(|s| s <= max)) {
            failed.push("seams");
        }
        failed
    }

    fn text(&self, c: &Claim) -> String {
        let f = |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{v:.2}"));
        let failed = self.failed(c);
        let verdict = if failed.is_empty() { "passes".to_string() } else { format!("✗ {}", failed.join("+")) };
        format!("rep {} con {:.2} seam {} {verdict}", f(self.repetition), self.contrast, f(self.seams))
    }
}

/// The served window and the model's own joins in it.
fn served(bundle: &Bundle) -> (Rgba8Image, Mask) {
    let tex = vtex_synth::models::load(bundle).unwrap();
    let img = render_image(&*tex, &Region::new(0, ORIGIN.0, ORIGIN.1, SIDE, SIDE)).unwrap();
    let joins = if bundle.manifest.model == chaos_mosaic::MODEL {
        let bits = chaos_mosaic::load(bundle).unwrap().seam_mask(ORIGIN.0, ORIGIN.1, SIDE, SIDE);
        Mask::from_bits(SIDE, SIDE, bits).unwrap()
    } else {
        let sources = order_independent::load(bundle).unwrap().sources(ORIGIN.0, ORIGIN.1, SIDE, SIDE);
        Mask::from_sources(SIDE, SIDE, |x, y| sources[(y * SIDE + x) as usize])
    };
    (img, joins)
}

/// The flat mean colour and the sample tiled from the window's corner, with the tiling's joins.
fn trivial(sample: &Rgba8Image) -> [(&'static str, Rgba8Image, Mask); 2] {
    let mut sums = [0u64; 3];
    for px in sample.data.chunks_exact(4) {
        (0..3).for_each(|c| sums[c] += px[c] as u64);
    }
    let n = sample.data.len() as u64 / 4;
    let mean = sums.map(|s| ((s + n / 2) / n) as u8);
    let mut flat = Rgba8Image::new(SIDE, SIDE);
    let mut tiled = Rgba8Image::new(SIDE, SIDE);
    for y in 0..SIDE {
        for x in 0..SIDE {
            flat.set_pixel(x, y, [mean[0], mean[1], mean[2], 255]);
            tiled.set_pixel(x, y, sample.pixel(x % sample.width, y % sample.height));
        }
    }
    let grid = Mask::grid(SIDE, SIDE, sample.width, sample.height, 0, 0);
    [("flat mean", flat, Mask::new(SIDE, SIDE)), ("verbatim tiling", tiled, grid)]
}

#[test]
fn every_claimed_gate_set_rejects_a_flat_colour_and_a_verbatim_tiling() {
    let mut problems = Vec::new();
    for claim in &CLAIMS {
        let demos: Vec<Bundle> =
            vtex_synth::models::demos().into_iter().filter(|b| b.manifest.model == claim.model).collect();
        assert!(!demos.is_empty(), "{}: no demos", claim.model);
        for bundle in demos {
            let sample = decode_png("sample.png", bundle.section("sample.png").unwrap()).unwrap();
            let name = format!("{}/{}", claim.model, bundle.manifest.name);
            let (img, joins) = served(&bundle);
            let served = Scores::of(&img, &sample, &joins);
            let tiling_on_purpose = bundle.manifest.params.get("iterations") == Some(&serde_json::json!(0));
            eprintln!("{name}: served {}", served.text(claim));
            for (answer, img, joins) in trivial(&sample) {
                let s = Scores::of(&img, &sample, &joins);
                eprintln!("{name}: {answer} {}", s.text(claim));
                if s.failed(claim).is_empty() {
                    problems.push(format!("{name}: the {answer} passes every gate ({s:?})"));
                }
            }
            // The chaos mosaic's zero-iteration demo is the plain tiling on purpose (the paper's
            // comparison), and claims nothing.
            if !tiling_on_purpose && !served.failed(claim).is_empty() {
                problems.push(format!("{name}: served fails {:?} ({served:?})", served.failed(claim)));
            }
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
}
