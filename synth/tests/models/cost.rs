//! The cost model against issue 17's hostile encodings: each is known for what it is from its
//! parameters and headers alone, and refused before any heavy work. "Before any heavy work"
//! is held by the bytes the refusing call allocates (a counting allocator, per thread), a
//! bound that drawing, decoding or generating would pass many times over.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use serde_json::{json, Value};
use vtex_synth::models::{self, Inputs, Limits};
use vtex_synth::texture::{level_count, level_size, render_image};
use vtex_synth::{Error, Region};

/// Counts the bytes each thread allocates, and those it holds (allocated less freed).
struct Counting;

thread_local! {
    static ALLOCATED: Cell<u64> = const { Cell::new(0) };
    static LIVE: Cell<i64> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATED.with(|a| a.set(a.get() + layout.size() as u64));
        LIVE.with(|l| l.set(l.get() + layout.size() as i64));
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.with(|l| l.set(l.get() - layout.size() as i64));
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATED.with(|a| a.set(a.get() + new_size as u64));
        LIVE.with(|l| l.set(l.get() + new_size as i64 - layout.size() as i64));
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

/// `f`'s result and the bytes it allocated on this thread.
fn allocated<T>(f: impl FnOnce() -> T) -> (T, u64) {
    let before = ALLOCATED.with(Cell::get);
    let out = f();
    (out, ALLOCATED.with(Cell::get) - before)
}

const MIB: u64 = 1 << 20;

/// A 4096² 1-bit black PNG: a few kilobytes that decode to 64 MiB of RGBA8.
fn one_bit_4096() -> Vec<u8> {
    let mut png = Vec::new();
    let mut encoder = png::Encoder::new(&mut png, 4096, 4096);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::One);
    encoder.set_compression(png::Compression::High);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(&vec![0u8; 4096 / 8 * 4096]).unwrap();
    writer.finish().unwrap();
    png
}

fn too_costly(r: vtex_synth::Result<impl Sized>) -> (&'static str, u64, String, u64) {
    match r {
        Err(Error::TooCostly { what, value, why, bound, .. }) => (what, value, why, bound),
        Err(e) => panic!("refused, but not for its cost: {e}"),
        Ok(_) => panic!("accepted"),
    }
}

#[test]
fn a_few_kilobyte_sample_is_known_to_hold_hundreds_of_mebibytes() {
    let sample = one_bit_4096();
    assert!(sample.len() < 8192, "{} bytes", sample.len());
    let inputs = Inputs::from([("sample".to_string(), sample)]);
    let params = json!({"tiles_x": 2, "tiles_y": 2, "seed": 1});
    let model = models::get("chaos-mosaic").unwrap();
    let (plan, bytes) = allocated(|| model.plan_create(&params, &inputs).unwrap());
    assert!(bytes < MIB, "the plan allocated {bytes} bytes");
    // Hundreds of mebibytes, but no more than 4× the sample's 64 MiB of RGBA8 (issue 34).
    let resident = plan.cost.resident_bytes.value;
    assert!((128 * MIB..=256 * MIB).contains(&resident), "{resident} bytes");
    assert_eq!((plan.width, plan.height), (8192, 8192));

    // Refused by a 128 MiB bound before the sample is decoded (64 MiB if it were).
    let limits = Limits { max_resident_bytes: 128 * MIB, ..Limits::NONE };
    let (r, bytes) = allocated(|| models::create_within("chaos-mosaic", "bomb", &params, &inputs, &limits));
    let (what, value, why, bound) = too_costly(r);
    assert_eq!((what, value, bound), ("resident bytes", resident, 128 * MIB));
    assert!(why.contains("4096×4096"), "{why}");
    assert!(bytes < MIB, "create_within allocated {bytes} bytes before refusing");
}

#[test]
fn a_mosaic_of_the_largest_sample_holds_at_most_four_times_its_rgba8() {
    let inputs = Inputs::from([("sample".to_string(), one_bit_4096())]);
    let params = json!({"tiles_x": 2, "tiles_y": 2, "seed": 1});
    let bundle = models::create("chaos-mosaic", "held", &params, &inputs).unwrap();
    let plan = models::plan(&bundle).unwrap().cost.resident_bytes.value;
    let before = LIVE.with(Cell::get);
    let tex = models::load(&bundle).unwrap();
    // A tile at every level: whatever a level builds on first use is held too.
    for level in 0..level_count(tex.width(), tex.height()) {
        let (w, h) = level_size(tex.width(), tex.height(), level);
        render_image(&*tex, &Region::new(level, w as i64 / 2, h as i64 / 2, 64, 64)).unwrap();
    }
    let held = (LIVE.with(Cell::get) - before) as u64;
    let rgba = 4 * 4096 * 4096;
    assert!(held <= plan, "held {held} bytes, planned {plan}");
    assert!(plan <= 4 * rgba + bundle.to_bytes().len() as u64, "planned {plan} bytes for {rgba} of RGBA8");
}

#[test]
fn a_twelve_stage_cascade_is_refused_for_its_tiles() {
    let stage = |s: usize| {
        let mut v =
            json!({"kernel": {"size": 7, "preset": "gauss"}, "map": {"kind": "logistic", "r": 3.9}, "iterations": 12});
        if s > 0 {
            v["upsample"] = json!(1);
        }
        v
    };
    let params = json!({"seed": 1, "range": [0.0, 1.0], "stages": (0..12).map(stage).collect::<Vec<Value>>()});
    let r = models::create_within("cascade", "deep", &params, &Inputs::new(), &Limits::SERVE);
    let (what, value, why, bound) = too_costly(r);
    assert_eq!(what, "work units per tile");
    assert!(value > 30_000_000_000 && value > bound, "{value} units is under 30 s of work");
    assert!(why.contains("12 stages"), "{why}");

    // Its first stage alone is an ordinary texture.
    let one = json!({"seed": 1, "range": [0.0, 1.0], "stages": [stage(0)]});
    models::create_within("cascade", "one", &one, &Inputs::new(), &Limits::SERVE).unwrap();
}

#[test]
fn sixty_lcm_layers_are_refused_before_any_is_drawn() {
    let table = json!({"width": 1, "height": 1, "cells": [{"sign": [0.0, 0.5, 0.5]}]});
    let layers: Vec<Value> =
        (0..60).map(|n| json!({"layer": n % 4, "lcm": [4096, 4096], "table": table.clone()})).collect();
    let params = json!({"element": {"builtin": "stroke", "k": 5}, "palette": [[-64, 0, 0, 0], [64, 255, 255, 255]], "layers": layers});
    let (r, bytes) = allocated(|| models::create("lcm", "sixty", &params, &Inputs::new()));
    match r {
        Err(Error::Param { name, reason }) => {
            assert!(name == "layers" && reason.contains("60 layers"), "{name}: {reason}")
        }
        other => panic!("{other:?}"),
    }
    // One drawn 4096² LCM alone is 16 MiB.
    assert!(bytes < MIB, "create allocated {bytes} bytes before refusing");
}

#[test]
fn the_most_blocks_a_mosaic_may_have_are_refused_for_their_making() {
    let inputs = Inputs::from([("sample".to_string(), vtex_synth::samples::pebbles(64, 8, 3, true).to_png())]);
    let params = json!({"tiles_x": 2048, "tiles_y": 2048, "seed": 1});
    let (r, bytes) = allocated(|| models::create_within("chaos-mosaic", "many", &params, &inputs, &Limits::SERVE));
    let (what, _, why, _) = too_costly(r);
    assert_eq!(what, "work units to build");
    assert!(why.contains("4194304 blocks"), "{why}");
    // Generating the blocks alone would take 16 bytes each.
    assert!(bytes < MIB, "create_within allocated {bytes} bytes before refusing");
}
