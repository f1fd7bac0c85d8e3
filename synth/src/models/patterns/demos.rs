//! The demo encodings (Fig. 10a, 10c, 14a, 14c, 15, 21a, 21c, 21d and the second LED
//! animation of the paper), every pattern drawn by [`super::art`]. Each demo is only data — params plus sections — for the one generic model.

use super::art::{self, Family};
use super::params::*;
use super::{pixel_map, sigma, MODEL};
use crate::{bundle::Bundle, Rgba8Image};
use std::collections::BTreeMap;

const SEED: u64 = 2003;
const S: u32 = 64;

/// Assembles a bundle from params, the packed reference and extra sections.
pub fn bundle(name: &str, p: &Params, reference: &Rgba8Image, sections: Vec<(&str, Vec<u8>)>) -> Bundle {
    let b = Bundle::new(MODEL, name, serde_json::to_value(p).expect("params serialize"))
        .with_section("reference.png", reference.to_png())
        .with_section("sigma", sigma::to_bytes(&sigma::generate_all(p.reference[0], p.reference[1], p.seed)));
    let mut b = super::plan::with_range_tables(b, p);
    for (n, d) in sections {
        b = b.with_section(n, d);
    }
    b
}

fn family(f: Family, seed: u64) -> Vec<Rgba8Image> {
    (0..16).map(|v| f.tile(seed, v, S)).collect()
}

/// Params of one tiling layer plus everything else defaulted.
fn params(width: u64, height: u64, reference: [u32; 2], layers: Vec<LayerParams>) -> Params {
    Params {
        width,
        height,
        pattern_size: S,
        reference,
        seed: SEED,
        background: [0, 0, 0, 0],
        layers,
        sprites: BTreeMap::new(),
        fps: None,
    }
}

fn layer(kind: LayerKind, cell: u32, choice: Option<Choice>) -> LayerParams {
    LayerParams { kind, cell, choice, transform: None, transitions: None, animation: None }
}

fn inline(w: u32, h: u32, values: Vec<u16>) -> MapRef {
    MapRef { size: [w, h], values: Some(values), section: None, depth: 1 }
}

/// The 8 × 8 areas map of the two-material demo: a blobby island of material 1.
fn island(w: u32, h: u32) -> Vec<u16> {
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (dx, dy) = (x as f32 - 3.2, y as f32 - 3.6);
            let r = (dx * dx * 0.8 + dy * dy).sqrt() + 0.9 * art::noise(5, x as f32, y as f32, 1.0, 8);
            (r < 3.1) as u16
        })
        .collect()
}

/// Fig. 10a: basic aperiodic tiling of 16 ground patterns over an `n × n` cell grid.
pub fn aperiodic(n: u64) -> Bundle {
    let (p, reference) = aperiodic_parts(n);
    let side = n * S as u64;
    bundle(&format!("Patterns: aperiodic tiling of 16 patterns ({side}²)"), &p, &reference, vec![])
}

/// The params and reference of [`aperiodic`].
fn aperiodic_parts(n: u64) -> (Params, Rgba8Image) {
    let reference = art::pack(&family(Family::Ground, SEED), 4, 4);
    let p = params(n * S as u64, n * S as u64, [4, 4], vec![layer(LayerKind::Tiling, S, Some(Choice::Virtual))]);
    (p, reference)
}

/// Fig. 10a's aperiodic tiling over 16 × 16 cells (1024²).
pub fn example() -> crate::models::Example {
    let (p, reference) = aperiodic_parts(16);
    crate::models::Example {
        params: serde_json::to_value(p).expect("params serialize"),
        inputs: vec![crate::models::ExampleInput {
            name: "reference".into(),
            what: "4 × 4 ground patterns of 64 × 64 pixels packed row-major, drawn by vtex (patterns::art)".into(),
            png: reference.to_png(),
        }],
    }
}

/// Ground (16) then grass (16) tiles, then 14 grass transition tiles: the Fig. 15 reference.
fn two_families() -> Rgba8Image {
    let mut pats = family(Family::Ground, SEED);
    pats.extend(family(Family::Grass, SEED + 1));
    pats.extend((1..=14).map(|m| Family::Grass.transition(SEED + 1, m, S)));
    art::pack(&pats, 8, 6)
}

/// Fig. 15: two material families, an 8 × 8 areas map, dithering and transition tiles.
pub fn two_materials() -> Bundle {
    let ground: Vec<i32> = (0..16).collect();
    // Grass with a probability map: plain variants (0..7 of the family) three times as often.
    let mut grass: Vec<i32> = (16..24).flat_map(|p| [p, p, p]).collect();
    grass.extend(24..32);
    let materials = vec![MaterialParams { patterns: ground, family: 0 }, MaterialParams { patterns: grass, family: 1 }];
    let choice = Choice::Materials {
        materials,
        areas: Some(AreasParams { map: inline(8, 8, island(8, 8)), dithered: true }),
        pixel_map: None,
    };
    let mut l = layer(LayerKind::Tiling, S, Some(choice));
    l.transitions = Some(TransitionParams { tiles: vec![(32..46).collect()] });
    let p = params(4096, 4096, [8, 6], vec![l]);
    bundle("Patterns: two materials, dithered 8×8 areas map, transition tiles (4096²)", &p, &two_families(), vec![])
}

/// Fig. 10c: a non-stationary distribution over one family of matching tiles — an 8 × 8
/// areas map (not dithered) of four materials, each a probability map over sand and
/// flowered sand; the sparsest flowers come from a probability map of 12 entries.
pub fn areas_map() -> Bundle {
    let mut pats = family(Family::Ground, SEED);
    pats.extend(family(Family::Meadow, SEED + 2));
    let reference = art::pack(&pats, 8, 4);
    let sand = MaterialParams { patterns: (0..16).collect(), family: 0 };
    let flowers = MaterialParams { patterns: (16..32).collect(), family: 0 };
    let mixed = MaterialParams { patterns: (0..8).chain(16..24).collect(), family: 0 };
    let few = MaterialParams { patterns: (0..10).chain([16, 21]).collect(), family: 0 };
    // Painted areas: flowers in a band, mixed around it, a few flowers elsewhere, sand at the corners.
    let areas: Vec<u16> = (0..64i32)
        .map(|i| {
            let (x, y) = (i % 8, i / 8);
            match (x - y).abs() {
                0 => 1,
                1 => 2,
                2 | 3 => 3,
                _ => 0,
            }
        })
        .collect();
    let choice = Choice::Materials {
        materials: vec![sand, flowers, mixed, few],
        areas: Some(AreasParams { map: inline(8, 8, areas), dithered: false }),
        pixel_map: None,
    };
    let p = params(4096, 4096, [8, 4], vec![layer(LayerKind::Tiling, S, Some(choice))]);
    bundle("Patterns: non-stationary tiling, 8×8 areas map of four materials (Fig. 10c, 4096²)", &p, &reference, vec![])
}

/// Fig. 14a: the basic sparse convolution — one leaf pattern (T = 1) at a random place,
/// scale and rotation in every cell, overflowing into its neighbours, on a plain background.
pub fn one_leaf() -> Bundle {
    let reference = art::leaf(SEED, 3, S);
    let mut l = layer(LayerKind::Sparse, S, Some(Choice::Virtual));
    l.transform = Some(TransformParams { scale: [0.6, 0.9], rotate: true, overflow: true });
    let mut p = params(4096, 4096, [1, 1], vec![l]);
    p.background = [118, 80, 46, 255];
    bundle("Patterns: sparse convolution of one leaf, random rotations (Fig. 14a, 4096²)", &p, &reference, vec![])
}

/// Ground (16) then leaves (8): the reference of the leaves and sprites demos.
fn ground_and_leaves() -> Rgba8Image {
    let mut pats = family(Family::Ground, SEED);
    pats.extend((0..8).map(|v| art::leaf(SEED, v, S)));
    art::pack(&pats, 6, 4)
}

fn ground_layer() -> LayerParams {
    let ground = MaterialParams { patterns: (0..16).collect(), family: 0 };
    layer(LayerKind::Tiling, S, Some(Choice::Materials { materials: vec![ground], areas: None, pixel_map: None }))
}

/// Fig. 14c: leaves scattered by sparse convolution with random rotation and scale,
/// overflowing into neighbouring cells, their density set by a dithered 8 × 8 areas map.
pub fn leaves() -> Bundle {
    let dense = MaterialParams { patterns: (16..24).collect(), family: 0 };
    let medium = MaterialParams { patterns: vec![16, 17, 18, 19, -1, -1, -1, -1], family: 0 };
    let sparse = MaterialParams { patterns: vec![20, -1, -1, -1, -1, -1, -1, -1], family: 0 };
    let density: Vec<u16> = (0..64).map(|i| [0u16, 1, 2, 1][((i % 8) / 2 + (i / 8) / 3) % 4]).collect();
    let choice = Choice::Materials {
        materials: vec![dense, medium, sparse],
        areas: Some(AreasParams { map: inline(8, 8, density), dithered: true }),
        pixel_map: None,
    };
    let mut l = layer(LayerKind::Sparse, 64, Some(choice));
    l.transform = Some(TransformParams { scale: [0.55, 0.95], rotate: true, overflow: true });
    let p = params(4096, 4096, [6, 4], vec![ground_layer(), l]);
    bundle("Patterns: leaves by sparse convolution, density areas map (4096²)", &p, &ground_and_leaves(), vec![])
}

/// Fig. 21d: texture sprites over a tiled ground; move them with a JSON merge patch of
/// `params.sprites.<name>`.
pub fn sprites() -> Bundle {
    let mut p = params(4096, 4096, [6, 4], vec![ground_layer(), layer(LayerKind::Sprites, 64, None)]);
    let spots = [
        ("maple", 16, 700, 400),
        ("oak", 17, 1510, 1333),
        ("birch", 18, 2222, 902),
        ("elm", 19, 3050, 2950),
        ("ash", 20, 530, 3180),
    ];
    for (name, pattern, x, y) in spots {
        p.sprites.insert(name.into(), SpriteParams::at(pattern, x, y));
    }
    bundle("Patterns: texture sprites on a tiled ground (4096²)", &p, &ground_and_leaves(), vec![])
}

/// Twelve LED states: off (rest), rising, on, falling.
fn led_reference() -> Rgba8Image {
    let levels = [0.0, 0.3, 0.65, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.65, 0.3];
    art::pack(&levels.map(|l| art::led(l, 32)), 4, 3)
}

/// The Z map of a message: short rests in the letters, long ones in the background.
fn led_z(text: &str, w: u32, h: u32) -> Vec<u8> {
    art::text_mask(text, w, h, 4).iter().map(|&on| if on { 0 } else { 240 }).collect()
}

/// Fig. 21c: the blinking LED message board, 12288 × 1536 (384 × 48 LEDs of 32 px). The
/// animation map gives every LED a random phase φ and a rest Z from the message map (plus a
/// little random jitter), so letters blink busily and the background flickers rarely.
/// With `transition`, the message changes at frame 120 by a temporal transition (§3.4).
pub fn led_board(transition: bool) -> Bundle {
    let (w, h) = (384u32, 48u32);
    let z = |section: &str| ValueParams {
        map: Some(MapRef { size: [w, h], values: None, section: Some(section.into()), depth: 1 }),
        random: 4,
    };
    let mut anim = AnimationParams {
        sequence: (0..12).collect(),
        a: 1.0,
        phi: ValueParams { map: None, random: 256 },
        z: z("z-new"),
        ..Default::default()
    };
    let mut sections = vec![("z-new", led_z("PATTERN TEXTURES", w, h))];
    let name = if transition {
        anim.previous = Some(Previous::One(PreviousParams { a: 1.0, z: z("z-old"), t0: 120 }));
        sections.push(("z-old", led_z("LEFEBVRE NEYRET", w, h)));
        "Patterns: LED board, temporal transition at frame 120 (12288×1536)"
    } else {
        "Patterns: blinking LED message board (12288×1536)"
    };
    let mut l = layer(LayerKind::Tiling, 32, None);
    l.animation = Some(anim);
    let mut p = params(w as u64 * 32, h as u64 * 32, [4, 3], vec![l]);
    p.pattern_size = 32;
    p.fps = Some(12.0);
    bundle(name, &p, &led_reference(), sections)
}

/// The Z map of a message with rests `letters` in the letters and `background` elsewhere.
fn led_z_of(text: &str, w: u32, h: u32, letters: u8, background: u8) -> Vec<u8> {
    art::text_mask(text, w, h, 4).iter().map(|&on| if on { letters } else { background }).collect()
}

/// The paper's second LED animation (§6): three Z maps — two messages and a blank panel —
/// and a density of animation `a` raised step by step to fade the first message out, then
/// lowered to fade the second in; every change is a temporal transition (§3.4), 2n frames
/// or more apart.
pub fn led_ramp() -> Bundle {
    let (w, h) = (384u32, 48u32);
    let z = |section: &str| ValueParams {
        map: Some(MapRef { size: [w, h], values: None, section: Some(section.into()), depth: 1 }),
        random: 4,
    };
    let blank = ValueParams { map: Some(inline(1, 1, vec![240])), random: 4 };
    // (a, Z) before each t0, in order; the second message at a = 1 after the last.
    let ramp = [
        (1.0, z("z-first"), 36),
        (2.0, z("z-first"), 60),
        (4.0, z("z-first"), 84),
        (8.0, z("z-first"), 108),
        (1.0, blank, 144),
        (8.0, z("z-second"), 168),
        (4.0, z("z-second"), 192),
        (2.0, z("z-second"), 216),
    ];
    let previous = ramp.into_iter().map(|(a, z, t0)| PreviousParams { a, z, t0 }).collect();
    let anim = AnimationParams {
        sequence: (0..12).collect(),
        a: 1.0,
        phi: ValueParams { map: None, random: 256 },
        z: z("z-second"),
        previous: Some(Previous::Many(previous)),
        ..Default::default()
    };
    let mut l = layer(LayerKind::Tiling, 32, None);
    l.animation = Some(anim);
    let mut p = params(w as u64 * 32, h as u64 * 32, [4, 3], vec![l]);
    p.pattern_size = 32;
    p.fps = Some(12.0);
    let sections = vec![
        ("z-first", led_z_of("PATTERN TEXTURES", w, h, 6, 240)),
        ("z-second", led_z_of("LEFEBVRE NEYRET", w, h, 6, 240)),
    ];
    bundle("Patterns: LED board, density ramp between two messages (12288×1536)", &p, &led_reference(), sections)
}

/// Fig. 21a: sequence textures triggered by the distance to two moving balls — LEDs light
/// up as a ball passes. The balls are texture sprites (scaled up after positioning) with a
/// velocity; the LEDs' sequence parameter is the distance to the nearest.
pub fn distance_triggered() -> Bundle {
    let mut pats: Vec<Rgba8Image> = [0.0, 0.3, 0.65, 1.0].map(|l| art::led(l, 32)).into();
    pats.push(art::ball(32));
    pats.extend((0..3).map(|_| Rgba8Image::new(32, 32)));
    let reference = art::pack(&pats, 4, 2);
    let mut leds = layer(LayerKind::Tiling, 32, None);
    leds.animation = Some(AnimationParams {
        sequence: vec![0, 1, 2, 3],
        distance: Some(DistanceParams { targets: vec!["east".into(), "south".into()], radius: 160.0 }),
        ..Default::default()
    });
    let mut p = params(4096, 4096, [4, 2], vec![leds, layer(LayerKind::Sprites, 128, None)]);
    p.pattern_size = 32;
    p.fps = Some(24.0);
    for (name, x, y, velocity) in [("east", 600, 900, [16, 4]), ("south", 2500, 300, [-4, 16])] {
        let mut ball = SpriteParams::at(4, x, y);
        ball.scale = 2.0;
        ball.velocity = velocity;
        p.sprites.insert(name.into(), ball);
    }
    bundle("Patterns: LEDs lit by the distance to two moving balls (Fig. 21a, 4096²)", &p, &reference, vec![])
}

/// A winding path of ground through grass at pixel precision: a pixel map (§3.3) at 1/4
/// resolution, compressed so only blocks on the path's border are stored.
pub fn pixel_map_path() -> Bundle {
    let (w, h, block) = (1024u32, 1024u32, 16u32);
    let mut mask = vec![0u8; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let fy = y as f32;
            let centre = 512.0
                + 260.0 * libm::sinf(fy / 1024.0 * 2.0 * core::f32::consts::PI)
                + 60.0 * (art::noise(3, x as f32, fy, 64.0, 16) - 0.5);
            mask[(y * w + x) as usize] = ((x as f32 - centre).abs() > 70.0) as u8;
        }
    }
    let ground = MaterialParams { patterns: (0..16).collect(), family: 0 };
    let grass = MaterialParams { patterns: (16..32).collect(), family: 1 };
    let pm = PixelMapParams { section: "path".into(), size: [w, h], scale: 4, block };
    let choice = Choice::Materials { materials: vec![ground, grass], areas: None, pixel_map: Some(pm) };
    let p = params(4096, 4096, [8, 6], vec![layer(LayerKind::Tiling, S, Some(choice))]);
    bundle(
        "Patterns: pixel-map path through grass (4096²)",
        &p,
        &two_families(),
        vec![("path", pixel_map::encode(w, h, block, &mask))],
    )
}

/// Every demo of the model.
pub fn demos() -> Vec<Bundle> {
    vec![
        aperiodic(64),
        aperiodic(1563),
        two_materials(),
        leaves(),
        sprites(),
        led_board(false),
        led_board(true),
        pixel_map_path(),
        areas_map(),
        one_leaf(),
        led_ramp(),
        distance_triggered(),
    ]
}
