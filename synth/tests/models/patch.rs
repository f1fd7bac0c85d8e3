//! A PATCH of a texture's params gives exactly what a fresh `create` of the patched params
//! gives: for every model, every field the user gave its example (one at a time, to a valid
//! other value) and some they left out, Cascade demo A's map, an `lcm` element and layer, and
//! a mosaic uploaded as a bundle. The patch is merged into the stored manifest's params as
//! the server merges it; the fresh texture is made from the user's own params, patched.

use serde_json::{json, Value};
use vtex_synth::bundle::{id_of, Bundle};
use vtex_synth::models::{self, lcm, merge_patch, remake_within, Inputs, Limits};
use vtex_synth::{texture::render_image, Region, Rgba8Image};
#[path = "../support/rgb_png.rs"]
mod rgb_png;
use rgb_png::rgb_png;

/// The merge patch (RFC 7396) that turns `from` into `to`: the changed fields of objects,
/// `null` for removed ones, anything else (arrays included) whole.
fn patch_between(from: &Value, to: &Value) -> Value {
    let (Value::Object(a), Value::Object(b)) = (from, to) else { return to.clone() };
    let removed = a.keys().filter(|k| !b.contains_key(*k)).map(|k| (k.clone(), Value::Null));
    let changed = b
        .iter()
        .filter(|(k, v)| a.get(*k) != Some(v))
        .map(|(k, v)| (k.clone(), patch_between(a.get(k).unwrap_or(&Value::Null), v)));
    Value::Object(removed.chain(changed).collect())
}

/// One texture to patch: its model, the params and inputs the user made it from, and the
/// bundle stored for it.
struct Made {
    model: &'static str,
    user: Value,
    inputs: Inputs,
    stored: Bundle,
}

impl Made {
    fn create(model: &'static str, name: &str, user: Value, inputs: Inputs) -> Made {
        let stored = models::create(model, name, &user, &inputs).unwrap_or_else(|e| panic!("{model}: {e}"));
        Made { model, user, inputs, stored }
    }

    fn example(model: &'static str) -> Made {
        let ex = models::get(model).unwrap().example();
        Made::create(model, &format!("{model} example"), ex.params.clone(), ex.inputs())
    }

    /// The stored texture patched by the server's route: `patch` merged into the stored
    /// params and the bundle made again.
    fn patched(&self, patch: &Value) -> vtex_synth::Result<Bundle> {
        let mut params = self.stored.manifest.params.clone();
        merge_patch(&mut params, patch);
        remake_within(&self.stored, &self.stored.manifest.name, &params, &Limits::NONE)
    }

    /// The PATCH that makes the edit of the user's params, against a fresh create of the
    /// edited params: what differs, or `None` when they are the same bundle.
    fn compare(&self, label: &str, edit: impl FnOnce(&mut Value)) -> Option<String> {
        let mut edited = self.user.clone();
        edit(&mut edited);
        assert_ne!(edited, self.user, "{}, {label}: the edit changes nothing", self.model);
        let fresh = models::create(self.model, &self.stored.manifest.name, &edited, &self.inputs)
            .unwrap_or_else(|e| panic!("{}, {label}: the edited params are invalid: {e}", self.model));
        assert_ne!(fresh.to_bytes(), self.stored.to_bytes(), "{}, {label}: not a different value", self.model);
        let failure = match self.patched(&patch_between(&self.user, &edited)) {
            Err(e) => format!("refused: {e}"),
            Ok(patched) if patched.to_bytes() != fresh.to_bytes() => format!(
                "another bundle ({} sections differ); patched params {}, fresh {}",
                patched.sections.iter().filter(|s| !fresh.sections.contains(s)).count(),
                patched.manifest.params,
                fresh.manifest.params
            ),
            Ok(patched) => {
                assert_eq!(id_of(&patched.to_bytes()), id_of(&fresh.to_bytes()));
                return None;
            }
        };
        Some(format!("{} {label}: {failure}", self.model))
    }
}

/// A named edit of the user's params.
type Edit = (&'static str, Box<dyn FnOnce(&mut Value)>);

/// Runs every edit of `made`, then fails listing every one whose PATCH did not give the fresh
/// texture.
fn check_all(made: &Made, edits: Vec<Edit>) {
    let failures: Vec<String> = edits.into_iter().filter_map(|(label, edit)| made.compare(label, edit)).collect();
    assert!(
        failures.is_empty(),
        "{} of the PATCHes differ from a fresh create:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Sets the field at `path` (a JSON pointer), which the user gave.
fn set(path: &'static str, value: Value) -> Edit {
    (
        path,
        Box::new(move |p: &mut Value| *p.pointer_mut(path).unwrap_or_else(|| panic!("{path}: no such field")) = value),
    )
}

/// Any other edit.
fn edit(label: &'static str, f: impl FnOnce(&mut Value) + 'static) -> Edit {
    (label, Box::new(f))
}

/// Adds a top-level field the user left out.
fn add(key: &'static str, value: Value) -> Edit {
    (key, Box::new(move |p: &mut Value| assert!(p.as_object_mut().unwrap().insert(key.into(), value).is_none())))
}

#[test]
fn every_cascade_field_patches_as_a_fresh_create() {
    let edits = vec![
        set("/seed", json!(2)),
        set("/width", json!(2048)),
        set("/height", json!(1024)),
        set("/palette", json!("fire")),
        set("/stages/0/kernel/size", json!(3)),
        set("/stages/0/kernel/sigma", json!(1.4)),
        set("/stages/0/map", json!({"kind": "tent", "mu": 1.6})),
        set("/stages/0/map/r", json!(3.3)),
        set("/stages/0/iterations", json!(4)),
        add("exact_levels", json!(1)),
        add("range", json!([0.2, 0.8])),
        edit("a second stage", |p| {
            let fine = json!({"upsample": 2, "kernel": {"size": 3, "preset": "gauss"},
                              "map": {"kind": "sine", "r": 0.95}, "iterations": 3});
            p["stages"].as_array_mut().unwrap().push(fine)
        }),
    ];
    check_all(&Made::example("cascade"), edits);
}

/// Cascade demo A's params, as `cascade::demos` makes it.
fn cascade_a() -> Made {
    let user = json!({"seed": 11, "stages": [{"kernel": {"size": 5, "preset": "gauss", "sigma": 1.0},
                      "map": {"kind": "logistic", "r": 3.9}, "iterations": 5}], "palette": "ocean"});
    let made = Made::create("cascade", "Cascade A — logistic ripples", user, Inputs::new());
    assert!(made.stored == models::cascade::demos()[0], "the demo's params are no longer these");
    made
}

/// Luma standard deviation of an image.
fn luma_sigma(img: &Rgba8Image) -> f64 {
    let luma: Vec<f64> =
        img.data.chunks_exact(4).map(|p| 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64).collect();
    let mean = luma.iter().sum::<f64>() / luma.len() as f64;
    (luma.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / luma.len() as f64).sqrt()
}

/// Demo A's logistic map moved from r = 3.9 to 3.3 must be mapped to colours by the range
/// of r = 3.3's values, not of 3.9's: the patched texture has the fresh one's contrast, not a
/// flat colour, and is the fresh one.
#[test]
fn cascade_a_patched_to_r_3_3_keeps_its_contrast() {
    let made = cascade_a();
    let mut edited = made.user.clone();
    edited["stages"][0]["map"]["r"] = json!(3.3);
    let fresh = models::create("cascade", &made.stored.manifest.name, &edited, &Inputs::new()).unwrap();
    let patched = made.patched(&json!({"stages": edited["stages"]})).unwrap();
    let region = Region::new(0, 0, 0, 256, 256);
    let render = |b: &Bundle| render_image(models::load(b).unwrap().as_ref(), &region).unwrap();
    let (sigma_patched, sigma_fresh) = (luma_sigma(&render(&patched)), luma_sigma(&render(&fresh)));
    println!("Cascade A, r 3.9 → 3.3: luma σ patched {sigma_patched:.1}, fresh {sigma_fresh:.1}");
    assert!(sigma_fresh > 20.0, "the fresh texture is flat: σ {sigma_fresh:.1}");
    assert!(
        (sigma_patched - sigma_fresh).abs() <= 0.1 * sigma_fresh,
        "σ patched {sigma_patched:.1}, fresh {sigma_fresh:.1}"
    );
    assert!(patched == fresh, "patched {:?}\nfresh {:?}", patched.manifest, fresh.manifest);
}

#[test]
fn every_chaos_mosaic_field_patches_as_a_fresh_create() {
    let edits = vec![
        set("/tiles_x", json!(8)),
        set("/tiles_y", json!(12)),
        set("/seed", json!(2)),
        add("iterations", json!(5)),
        add("blocks_per_tile", json!(2)),
        add("c_lambda", json!(0.4)),
        add("c_mu", json!(0.7)),
        add("sequence", json!("explicit")),
        add("seamless", json!(false)),
        add("filter_width", json!(2)),
    ];
    check_all(&Made::example("chaos-mosaic"), edits);
}

/// A mosaic uploaded as a bundle a user assembled: a manifest naming its params and the
/// sample as their own PNG. A new seed is what creating it from those params and that sample
/// makes.
#[test]
fn a_mosaic_uploaded_as_a_bundle_takes_a_new_seed() {
    let sample = rgb_png(&vtex_synth::samples::pebbles(64, 10, 3, true));
    let user = json!({"tiles_x": 16, "tiles_y": 16, "seed": 1, "seamless": true});
    let uploaded =
        Bundle::new("chaos-mosaic", "uploaded pebbles", user.clone()).with_section("sample.png", sample.clone());
    let uploaded = Bundle::from_bytes(&uploaded.to_bytes()).unwrap();
    models::load(&uploaded).expect("a valid bundle");
    let inputs = Inputs::from([("sample".to_string(), sample)]);
    let made = Made { model: "chaos-mosaic", user, inputs, stored: uploaded };
    check_all(&made, vec![set("/seed", json!(2)), set("/tiles_x", json!(8))]);
}

#[test]
fn every_order_independent_field_patches_as_a_fresh_create() {
    let edits = vec![
        set("/seed", json!(2)),
        set("/width", json!(2048)),
        set("/height", json!(1024)),
        set("/exemplar_wrap", json!(false)),
        add("search", json!("exhaustive")),
        add("generation0", json!("search")),
        add("domain", json!("torus")),
        add("levels", json!(3)),
        add("generations", json!(2)),
        add("coarsest_generations", json!(2)),
        add("neighbourhood", json!({"same": "square3"})),
        add("k", json!(3)),
        add("k_exclusion", json!(1)),
        add("kappa", json!(50)),
        add("jitter", json!(2)),
        add("subpasses", json!(1)),
        add("mip", json!({"exact_levels": 1})),
    ];
    check_all(&Made::example("order-independent"), edits);
}

#[test]
fn every_lcm_field_patches_as_a_fresh_create() {
    let noise_layer = |layer: u32| json!({"layer": layer, "weight": 0.2, "lcm": [20, 20], "table": serde_json::to_value(lcm::demos::table_noise()).unwrap()});
    let edits = vec![
        set("/element/k", json!(6)),
        set("/element/builtin", json!("stroke")),
        set("/seed", json!(4)),
        set("/tiles", json!([1, 1])),
        set("/palette/0/0", json!(-90.0)),
        set("/representation", json!("haar")),
        set("/mask_coding", json!("raw")),
        set("/magnify", json!(1)),
        set("/order", json!("bottom_up")),
        set("/layers/0/weight", json!(0.5)),
        set("/layers/0/lcm", json!([20, 20])),
        set("/layers/0/layer", json!(1)),
        set("/layers/0/table", serde_json::to_value(lcm::demos::table_noise()).unwrap()),
        edit("a layer added", move |p| p["layers"].as_array_mut().unwrap().push(noise_layer(2))),
        add("background", json!([10.0])),
    ];
    check_all(&Made::example("lcm"), edits);
}

#[test]
fn every_patterns_field_patches_as_a_fresh_create() {
    let edits = vec![
        set("/seed", json!(7)),
        set("/width", json!(2048)),
        set("/height", json!(512)),
        set("/background", json!([10, 20, 30, 255])),
    ];
    check_all(&Made::example("patterns"), edits);
}

/// A bundle whose parts were not made by its params cannot be remade from them: refused,
/// naming the patched field and the part, while a rename keeps everything.
#[test]
fn parts_not_made_by_the_params_refuse_a_patch_by_name() {
    let refusal = |b: &Bundle| {
        let mut params = b.manifest.params.clone();
        merge_patch(&mut params, &json!({"seed": 9}));
        remake_within(b, "edited", &params, &Limits::NONE).unwrap_err().to_string()
    };
    // An explicit block sequence, one block moved by hand.
    let ex = models::get("chaos-mosaic").unwrap().example();
    let mut params = ex.params.clone();
    params["sequence"] = json!("explicit");
    let mut b = models::create("chaos-mosaic", "edited blocks", &params, &ex.inputs()).unwrap();
    b.sections.iter_mut().find(|s| s.name == "blocks").unwrap().data[0] ^= 1;
    models::load(&b).expect("still a valid bundle");
    let e = refusal(&b);
    assert!(e.contains("`seed`") && e.contains("section `blocks`"), "{e}");
    // A derived range chosen by hand.
    let ex = models::get("cascade").unwrap().example();
    let mut b = models::create("cascade", "edited range", &ex.params, &ex.inputs()).unwrap();
    b.manifest.derived.insert("range".into(), json!([0.1, 0.9]));
    models::load(&b).expect("still a valid bundle");
    let e = refusal(&b);
    assert!(e.contains("`seed`") && e.contains("derived `range`"), "{e}");
    let renamed = remake_within(&b, "renamed", &b.manifest.params, &Limits::NONE).unwrap();
    assert_eq!((renamed.manifest.name.as_str(), &renamed.sections), ("renamed", &b.sections));
    assert_eq!(renamed.manifest.derived, b.manifest.derived);
}
