//! Renders stop when asked. Every model polls its [`Stop`] between bands of work: often (a
//! 256² render polls more than once) and promptly (a stop requested at poll n ends the render
//! within a few more polls). Work is counted in polls, never in time, so these hold on any
//! machine; a render that ignored its stop would instead run to its end.
//!
//! `cargo test --release -p vtex-synth --test models stop::`

use serde_json::json;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use vtex_synth::models::{self, cascade::demos::control_map, Inputs};
use vtex_synth::texture::{level_count, level_size, render_image, render_image_until};
use vtex_synth::{Region, Stop, Texture};

/// Polls a render may make after the first that finds its stop requested: one a nesting of
/// loops that each poll on their way out.
const FEW: usize = 2;

const TILE: u32 = 256;

/// A stop that counts its polls and is requested from poll `at` on.
struct After {
    at: usize,
    polls: AtomicUsize,
}

impl After {
    fn new(at: usize) -> Self {
        Self { at, polls: AtomicUsize::new(0) }
    }

    fn polls(&self) -> usize {
        self.polls.load(Ordering::Relaxed)
    }
}

impl Stop for After {
    fn requested(&self) -> bool {
        self.polls.fetch_add(1, Ordering::Relaxed) + 1 >= self.at
    }
}

/// The tile at (3, 5) tiles of `level`.
fn tile(level: u32) -> Region {
    Region::new(level, 3 * TILE as i64, 5 * TILE as i64, TILE, TILE)
}

/// Renders `region` with a stop requested at poll `at`; returns the polls made.
fn polls_until(tex: &dyn Texture, region: &Region, at: usize) -> usize {
    let stop = After::new(at);
    let mut out = vec![0u8; region.byte_len()];
    tex.render(region, &mut out, &stop);
    stop.polls()
}

/// A stop requested at poll `at` ends the render within [`FEW`] more polls.
fn assert_prompt(label: &str, tex: &dyn Texture, region: &Region, at: usize) {
    let polls = polls_until(tex, region, at);
    assert!(polls <= at + FEW, "{label}: requested at poll {at}, it polled {polls} times");
}

/// The levels every demo is checked at: level 0, the middle one, and the last at which the
/// texture still fills a tile (its coarsest banded work).
fn levels(tex: &dyn Texture) -> [u32; 3] {
    let n = level_count(tex.width(), tex.height());
    let fill = (0..n).rev().find(|&l| level_size(tex.width(), tex.height(), l).0 >= TILE as u64);
    [0, n / 2, fill.unwrap_or(0)]
}

#[test]
fn every_demo_polls_often_and_stops_promptly() {
    for bundle in models::demos() {
        let name = format!("{}/{}", bundle.manifest.model, bundle.manifest.name);
        let tex = models::load(&bundle).unwrap();
        for level in levels(tex.as_ref()) {
            let label = format!("{name} level {level}");
            let region = tile(level).at_frame(tex.animation().map_or(0, |_| 7));
            // Requested at its first poll, before anything is cached (a first render of a
            // prefiltered level computes the texture's statistics, and stops there too).
            assert_prompt(&label, tex.as_ref(), &region, 1);
            // Banded: a render asked to stop at its second poll gets there.
            let polls = polls_until(tex.as_ref(), &region, 2);
            assert!(polls >= 2, "{label}: a {TILE}² render polled {polls} times; it is not banded");
            for at in [2, 5, 50] {
                assert_prompt(&label, tex.as_ref(), &region, at);
            }
        }
    }
}

/// A render stopped part way leaves nothing behind: the statistics a cascade computes on the
/// first render of a prefiltered level are kept only when complete, so the next render is
/// the one a fresh texture gives.
#[test]
fn a_stopped_render_leaves_nothing_behind() {
    let bundle = models::get("cascade").unwrap().demos().swap_remove(0);
    let tex = models::load(&bundle).unwrap();
    let region = tile(8);
    for at in [1, 10, 100, 1000, 10_000] {
        let stop = After::new(at);
        assert_eq!(render_image_until(tex.as_ref(), &region, &stop).unwrap(), None, "stopped at poll {at}");
    }
    let fresh = render_image(models::load(&bundle).unwrap().as_ref(), &region).unwrap();
    assert_eq!(render_image(tex.as_ref(), &region).unwrap(), fresh);
}

/// A cascade polls within every iteration of every stage: at least once a row of each
/// iteration's window, which is at least as tall as the tile when no stage is coarser.
#[test]
fn a_cascade_polls_every_row_of_every_iteration() {
    let stages: Vec<_> = (0..4)
        .map(|s| {
            let mut st = json!({"kernel": {"size": 3, "preset": "box"}, "map": {"kind": "logistic", "r": 3.7},
                                "iterations": 6});
            if s > 0 {
                st["upsample"] = json!(1);
            }
            st
        })
        .collect();
    let params = json!({"seed": 2, "stages": stages, "range": [0.1, 0.9]});
    let tex = models::load(&models::create("cascade", "rows", &params, &Inputs::new()).unwrap()).unwrap();
    let region = Region::new(0, 0, 0, 64, TILE);
    let polls = polls_until(tex.as_ref(), &region, usize::MAX);
    assert!(polls >= 4 * 6 * TILE as usize, "{polls} polls for 4 stages of 6 iterations over {TILE} rows");
}

/// The dearest cascade the bounds allow a tile (twelve stages of 64 iterations of a 7 × 7
/// kernel read bilinearly through a dilation map): a tile of it takes minutes, a stop at poll n
/// ends it within a few polls at every level, through level 0, the exact levels, the
/// statistics of the prefiltered ones and the guided coarsest ones.
#[test]
fn the_dearest_cascade_stops_promptly_at_every_level() {
    let stage = |first: bool| {
        let mut s = json!({"kernel": {"size": 7, "preset": "gauss"}, "map": {"kind": "logistic", "r": 3.7},
                           "iterations": 64, "jitter": 0.1});
        if !first {
            s["upsample"] = json!(2);
        }
        s
    };
    let stages: Vec<_> = (0..12).map(|s| stage(s == 0)).collect();
    let params = json!({"seed": 5, "stages": stages, "range": [0.1, 0.9], "exact_levels": 3,
                        "dilation_map": {"max": 2, "cell": 4096}});
    let inputs = Inputs::from([("control".to_string(), control_map(16).to_png())]);
    let tex: Arc<dyn Texture> = models::load(&models::create("cascade", "dear", &params, &inputs).unwrap()).unwrap();
    for level in 0..level_count(tex.width(), tex.height()) {
        let region = tile(level);
        for at in [1, 2, 7, 64] {
            assert_prompt(&format!("level {level}"), tex.as_ref(), &region, at);
        }
    }
}
