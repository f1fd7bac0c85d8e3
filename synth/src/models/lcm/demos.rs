//! The demo encodings of the paper's §3, from the project-made elements of [`super::elements`]:
//! "random rotation" (Tab. 1), "cheese", "brick wall" simple and with the noise layers of
//! Tab. 2 (Tab. 3, §6's 40 × 40 + 20 × 20 LCMs and 640 × 640 period), and a 100,352 ×
//! 100,352 colour texture of pebbles (one element plane per channel).

use super::encoding::{create, PEBBLE_SAND};
use super::packing::MaskCoding;
use super::params::{Builtin, LayerParams, Order, Params, Representation};
use super::table::{Cell, Table};
use crate::bundle::Bundle;
use crate::models::Inputs;
use crate::Result;

const UNIFORM: [f64; 4] = [0.25; 4];
const ADD: [f64; 3] = [1.0, 0.0, 0.0];
const NON_ZERO: [f64; 3] = [0.0, 1.0, 0.0];

fn layer(layer: u32, weight: f64, lcm: [u32; 2], table: Table) -> LayerParams {
    LayerParams { layer, weight, lcm, share: None, table: Some(table) }
}

/// Tab. 1: two staggered "no replication" entries, two of uniform rotation.
pub fn table_random_rotation() -> Table {
    let on = Cell::positive(UNIFORM, 0.0, ADD);
    Table { width: 2, height: 2, cells: vec![Cell::none(), on.clone(), on, Cell::none()] }
}

/// Tab. 2: the "simple noise" model.
pub fn table_noise() -> Table {
    Table::single(Cell { sign: [0.33, 0.33, 0.34], rotation: UNIFORM, mirror: 0.5, operation: ADD })
}

/// Tab. 3: the "brick wall" model, non-zero application. The paper prints four event cells
/// and, between them, the large "0" of zero cells, as in Tab. 1: a 4 × 2 table whose rows are
/// (cell, 0, cell, 0) and (0, cell, 0, cell) — the staggered "regularly structured zero
/// entries" §6 says Tab. 3's masks have. The cells in the order printed: the first row's two
/// (mostly 0° / mostly 180°, "each two elements in any row are 180° rotated copies"), then
/// the second row's two.
pub fn table_brick() -> Table {
    let c = |r: [f64; 4]| Cell::positive(r, 0.0, NON_ZERO);
    let o = Cell::none;
    Table {
        width: 4,
        height: 2,
        cells: vec![
            c([0.8, 0.05, 0.15, 0.0]),
            o(),
            c([0.2, 0.0, 0.8, 0.0]),
            o(),
            o(),
            c([0.75, 0.05, 0.2, 0.0]),
            o(),
            c([0.1, 0.02, 0.88, 0.0]),
        ],
    }
}

fn params(element: &str, k: u32, layers: Vec<LayerParams>) -> Params {
    Params {
        element: Some(Builtin { builtin: element.into(), k }),
        k: None,
        planes: None,
        representation: Representation::Explicit,
        stored_resolutions: Vec::new(),
        magnify: 0,
        background: None,
        order: Order::TopDown,
        palette: Vec::new(),
        tiles: [1, 1],
        mask_coding: MaskCoding::Zeros,
        seed: 1,
        layers,
    }
}

/// "Random rotation": 4 layers of the zero-mean stroke, Tab. 1 on each, weights 1. The two
/// large layers do not tile (§5): LCMs of 160 × 150 and 320 × 300 points at 64 and 32 px
/// cover the 10,240 × 9,600 texture. The small layers tile with periods that are not
/// multiples of each other, 2,048 × 1,920 and 1,280 × 1,200 px.
pub fn random_rotation() -> Params {
    let t = table_random_rotation;
    Params {
        palette: vec![[-160.0, 16.0, 34.0, 78.0], [160.0, 246.0, 236.0, 206.0]],
        seed: 11,
        ..params(
            "stroke",
            7,
            vec![
                layer(0, 1.0, [160, 150], t()),
                layer(1, 1.0, [320, 300], t()),
                layer(2, 1.0, [128, 120], t()),
                layer(3, 1.0, [160, 150], t()),
            ],
        )
    }
}

/// "Cheese": one hole element at two scales, rarely replicated, holes painted over each other.
/// Neither layer tiles: LCMs of 200 × 200 and 400 × 400 points at 32 and 16 px cover the
/// 6,400² texture.
pub fn cheese() -> Params {
    let holes =
        |p: f64| Table::single(Cell { sign: [p, 0.0, 1.0 - p], rotation: UNIFORM, mirror: 0.5, operation: NON_ZERO });
    Params {
        palette: vec![
            [-130.0, 120.0, 78.0, 14.0],
            [-60.0, 196.0, 146.0, 40.0],
            [0.0, 240.0, 204.0, 100.0],
            [45.0, 254.0, 236.0, 168.0],
        ],
        seed: 5,
        ..params("hole", 6, vec![layer(0, 1.0, [200, 200], holes(0.08)), layer(1, 1.0, [400, 400], holes(0.05))])
    }
}

/// Two stops: an affine map from intensity to colour commutes with the box filter, so the
/// native mip levels (filtered in intensity) match the exact ones (filtered in colour).
fn brick_palette() -> Vec<[f64; 4]> {
    // Mortar (−62) is (190, 186, 178), brick (50) is (160, 84, 64); the ends leave room for
    // the noise layers without clamping.
    vec![[-110.0, 203.0, 230.0, 227.0], [110.0, 144.0, 29.0, 3.0]]
}

/// "Brick wall", simple (Fig. 3 centre): Tab. 3 on layer 0 only.
pub fn brick_wall_simple() -> Params {
    Params {
        palette: brick_palette(),
        seed: 3,
        tiles: [2, 2],
        ..params("brick", 5, vec![layer(0, 1.0, [40, 40], table_brick())])
    }
}

/// "Brick wall" (Fig. 3 right, §6): Tab. 3 on layer 0 (LCM 40 × 40) and the element again as
/// noise (Tab. 2) with weight 0.2 on layers 2 and 3, which share one 20 × 20 LCM — the
/// 40² + 20² + 32² + 8² + 4² = 3,104 bytes of the paper, for a 640 × 640 period.
pub fn brick_wall() -> Params {
    let mut shared = layer(3, 0.2, [20, 20], table_noise());
    shared.share = Some(1);
    Params {
        palette: brick_palette(),
        seed: 3,
        tiles: [2, 2],
        ..params(
            "brick",
            5,
            vec![layer(0, 1.0, [40, 40], table_brick()), layer(2, 0.2, [20, 20], table_noise()), shared],
        )
    }
}

/// Pebbles on sand, 100,352 × 100,352: five layers of a 256-px colour pebble (one plane per
/// channel), small ones first and the largest on top, over a faint sand noise. The large layer
/// does not tile (§5): its 784 × 784 LCM at 128-px spacing covers the whole texture. Layer 1
/// (392 × 392 at 64 px) repeats every 25,088 px and the small layers every 2,048, 1,024 and
/// 512 px, so no two of the two large layers' repetitions meet within the texture. Its masks
/// (768,320 points, 337 kB zero-coded) are drawn again at load from the seed.
pub fn pebbles() -> Params {
    let stones = |pos: f64, neg: f64| {
        Table::single(Cell { sign: [pos, neg, 1.0 - pos - neg], rotation: UNIFORM, mirror: 0.5, operation: NON_ZERO })
    };
    Params {
        background: Some(PEBBLE_SAND.to_vec()),
        order: Order::BottomUp,
        mask_coding: MaskCoding::Drawn,
        seed: 100_352,
        ..params(
            "pebble",
            8,
            vec![
                layer(0, 1.0, [784, 784], stones(0.2, 0.1)),
                layer(1, 0.9, [392, 392], stones(0.25, 0.12)),
                layer(2, 0.8, [64, 64], stones(0.3, 0.15)),
                layer(3, 0.7, [64, 64], stones(0.3, 0.2)),
                layer(4, 0.25, [64, 64], table_noise()),
            ],
        )
    }
}

/// The named demo parameter sets.
pub fn all_params() -> Vec<(&'static str, Params)> {
    vec![
        ("LCM random rotation", random_rotation()),
        ("LCM cheese", cheese()),
        ("LCM brick wall (simple)", brick_wall_simple()),
        ("LCM brick wall", brick_wall()),
        ("LCM pebbles 100k", pebbles()),
    ]
}

/// Makes one demo's encoding.
pub fn make(name: &str, p: &Params) -> Result<Bundle> {
    let json = serde_json::to_value(p).expect("demo parameters serialize");
    create(name, &json, &Inputs::new())
}

/// Every demo encoding.
pub fn demos() -> Vec<Bundle> {
    all_params().iter().map(|(n, p)| make(n, p).expect("the demos are valid encodings")).collect()
}

/// The simple brick wall (a built-in element, one 40 × 40 LCM): no input images.
pub fn example() -> crate::models::Example {
    crate::models::Example {
        params: serde_json::to_value(brick_wall_simple()).expect("demo parameters serialize"),
        inputs: Vec::new(),
    }
}
