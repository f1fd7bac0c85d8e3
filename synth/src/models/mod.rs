//! The texture models, and the registry through which the rest of vtex reaches them.
//!
//! Every model is one module with the same layout — `mod.rs` (what the model is, and its
//! [`Model`] implementation: the registry entry), `params.rs` (its creation parameters),
//! `plan.rs` (the encoding's limits and checks, and its cost), `render.rs` (the loaded
//! texture), `encoding.rs` (parameters and inputs to a [`Bundle`], and a bundle back to a
//! validated texture), `demos.rs` — plus its own internals; `encoding` imports `render`,
//! which imports `plan`, never the other way. [`REGISTRY`] lists one entry per model;
//! nothing else in vtex names a model, so adding one is a module and a line there (and in
//! [`ALL`], with its `model-*` feature in `Cargo.toml`).
//!
//! A build holds the models of its `model-*` features; without the `create` feature it only
//! loads and renders (no `create`, demos, examples or parameter schemas), which is what a
//! client that synthesizes tiles of one model needs.

use crate::resources::{Resources, Shared};
use crate::{bundle::Bundle, Error, Result, Texture};
#[cfg(feature = "create")]
use std::collections::BTreeMap;
use std::sync::{Arc, LazyLock};

pub use cost::{Cost, Limits, Measure, Plan};

#[cfg(feature = "model-cascade")]
pub mod cascade;
#[cfg(feature = "model-chaos-mosaic")]
pub mod chaos_mosaic;
pub mod cost;
#[cfg(feature = "model-lcm")]
pub mod lcm;
#[cfg(feature = "model-order-independent")]
pub mod order_independent;
#[cfg(feature = "model-patterns")]
pub mod patterns;
#[cfg(feature = "create")]
mod remake;

#[cfg(feature = "create")]
pub use remake::{merge_patch, remake_within};

/// Input images by name (PNG bytes), e.g. `sample` for the chaos mosaic.
#[cfg(feature = "create")]
pub type Inputs = BTreeMap<String, Vec<u8>>;

/// One texture model: everything the rest of vtex may know about it.
pub trait Model: Send + Sync + 'static {
    /// The id used in bundles, URLs and the CLI (`chaos-mosaic`, `lcm`, …).
    fn id(&self) -> &'static str;
    #[cfg(feature = "create")]
    /// What it is and how it is made: for listings, `--help`, and generic checks.
    fn describe(&self) -> ModelInfo;
    #[cfg(feature = "create")]
    /// Makes a new encoding from JSON parameters and named input images (PNG bytes).
    fn create(&self, name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle>;
    #[cfg(feature = "create")]
    /// The input images `create` made `bundle` from, recovered from its sections: `create`
    /// with them and the manifest's params makes the bundle again, bit for bit (held for every
    /// demo by the tests; [`remake_within`] checks it before it changes a parameter).
    fn inputs_of(&self, bundle: &Bundle) -> Result<Inputs>;
    /// Validates a bundle of this model completely and returns its texture, which shares
    /// `resources` with the others loaded with them.
    fn load(&self, bundle: &Bundle, resources: &Resources) -> Result<Arc<dyn Texture>>;
    /// What `load(bundle)` would give and cost, from the manifest, section lengths and image
    /// headers alone: nothing drawn, generated, indexed or decoded.
    fn plan(&self, bundle: &Bundle) -> Result<Plan>;
    /// Checks what `load` takes on trust because recomputing it on every open would cost more
    /// than the open: data derived from the params and inputs that `create` stores in the
    /// bundle must be exactly what they derive. `load` still checks its shape strictly; this
    /// recomputes it. Called once where a bundle from outside is accepted (the server's
    /// upload, [`verify`]), never on open; a bundle `create` made passes by construction.
    /// Most models store nothing of the kind.
    #[cfg(feature = "create")]
    fn verify(&self, _bundle: &Bundle) -> Result<()> {
        Ok(())
    }
    /// The sections that only hold what `load` would otherwise derive from the rest of the
    /// bundle (a bundle stored before one existed renders the same without it, deriving it
    /// when needed): [`remake_within`] does not count one `create` adds as a part the stored
    /// bundle was not made with.
    #[cfg(feature = "create")]
    fn cached_sections(&self) -> &'static [&'static str] {
        &[]
    }
    #[cfg(feature = "create")]
    /// What `create(name, params, inputs)` would give and cost, from the parameters and the
    /// inputs' headers alone; refuses every parameter `create` would refuse.
    fn plan_create(&self, params: &serde_json::Value, inputs: &Inputs) -> Result<Plan>;
    #[cfg(feature = "create")]
    /// Its demo encodings, from project-made inputs only.
    fn demos(&self) -> Vec<Bundle>;
    #[cfg(feature = "create")]
    /// Parameters and project-made inputs that `create` turns into a small texture quickly:
    /// what a newcomer starts from (`GET /api/v1/models`, `vtex models`).
    fn example(&self) -> Example;
    /// What its prefiltered coarse levels promise, held by the conformance suite.
    fn mip_guarantee(&self) -> MipGuarantee;
    /// Its part of a [`Resources`] — caches (holding at most `cache_budget` bytes) and work
    /// counters that its textures loaded with those resources share — when it has any.
    fn resources(&self, _cache_budget: u64) -> Option<Shared> {
        None
    }
}

/// A model's self-description.
#[cfg(feature = "create")]
#[derive(Clone, Debug, PartialEq)]
pub struct ModelInfo {
    pub id: &'static str,
    /// Human name, e.g. "Chaos mosaic".
    pub title: &'static str,
    /// The publication the model implements: authors, year, title.
    pub paper: &'static str,
    /// One sentence.
    pub summary: &'static str,
    /// JSON Schema of `create`'s params, generated from the model's `Params` type.
    pub params_schema: serde_json::Value,
    /// Named input images `create` accepts or needs.
    pub inputs: &'static [InputInfo],
}

/// One input image of [`Model::create`].
#[cfg(feature = "create")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InputInfo {
    /// The key in [`Inputs`]; `*` stands for any name the parameters give an input.
    pub name: &'static str,
    pub required: bool,
    /// What the image holds and how it is read.
    pub what: &'static str,
}

/// A small, quick creation of a model ([`Model::example`]).
#[cfg(feature = "create")]
#[derive(Clone, Debug, PartialEq)]
pub struct Example {
    /// `create`'s parameters.
    pub params: serde_json::Value,
    /// Every input image `params` needs, in the order of [`ModelInfo::inputs`].
    pub inputs: Vec<ExampleInput>,
}

/// One input image of an [`Example`].
#[cfg(feature = "create")]
#[derive(Clone, Debug, PartialEq)]
pub struct ExampleInput {
    /// The key in [`Inputs`].
    pub name: String,
    /// What the image shows and how it was made.
    pub what: String,
    /// PNG bytes.
    pub png: Vec<u8>,
}

#[cfg(feature = "create")]
#[cfg(feature = "create")]
impl Example {
    /// The inputs as `create` takes them.
    pub fn inputs(&self) -> Inputs {
        self.inputs.iter().map(|i| (i.name.clone(), i.png.clone())).collect()
    }
}

/// What a model's prefiltered coarse levels promise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MipGuarantee {
    /// PSNR (dB) every level L ≥ 1 keeps against three exact 2×2 box downsamples of level L−3
    /// (fewer near level 0; any region). Where a texture's coarse levels are hard to predict
    /// (large dark patches of a pebble sample) this floor sits below what point sampling scores
    /// elsewhere; the σ gate and `beats_trivial_answers` then hold the level to its texture.
    pub min_psnr_db: f64,
    /// Largest |mean difference| (0–255 per channel) of every level against the same box chain,
    /// and of the coarsest level against the true mean.
    pub max_mean_error: f64,
    /// Largest relative difference of every level's σ from the same box chain's: a flat colour
    /// fails it, and so does a level that keeps only part of the texture's contrast
    /// (`f64::INFINITY`: no promise).
    pub max_sigma_error: f64,
    /// Every level where the box chain has visible contrast scores at least as well as a flat
    /// colour and as point sampling, and the gates reject both of them at some level.
    /// A model that cannot promise it says so here; the conformance table shows where it falls
    /// short.
    pub beats_trivial_answers: bool,
}

/// Every model of vtex by id, in registry order, whether or not this build holds it.
pub const ALL: &[&str] = &["cascade", "chaos-mosaic", "lcm", "order-independent", "patterns"];

/// Every model this build holds (its `model-*` features), one line each.
pub static REGISTRY: &[&dyn Model] = &[
    #[cfg(feature = "model-cascade")]
    &cascade::CASCADE,
    #[cfg(feature = "model-chaos-mosaic")]
    &chaos_mosaic::CHAOS_MOSAIC,
    #[cfg(feature = "model-lcm")]
    &lcm::LCM,
    #[cfg(feature = "model-order-independent")]
    &order_independent::ORDER_INDEPENDENT,
    #[cfg(feature = "model-patterns")]
    &patterns::PATTERNS,
];

/// The model ids as a list, in registry order.
pub static MODELS: LazyLock<Vec<&'static str>> = LazyLock::new(|| ids().collect());

/// The registered model called `id`; a model of vtex that this build leaves out is an error
/// naming the models it holds.
pub fn get(id: &str) -> Result<&'static dyn Model> {
    REGISTRY.iter().copied().find(|m| m.id() == id).ok_or_else(|| {
        let known = ids().collect::<Vec<_>>().join(", ");
        if ALL.contains(&id) {
            Error::NotBuilt { model: id.into(), built: known }
        } else {
            Error::UnknownModel { model: id.into(), known }
        }
    })
}

/// The registered model ids, in registry order.
pub fn ids() -> impl Iterator<Item = &'static str> {
    REGISTRY.iter().map(|m| m.id())
}

/// Makes a new encoding of `model` from its JSON parameters and input images.
#[cfg(feature = "create")]
pub fn create(model: &str, name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    check_name(name)?;
    get(model)?.create(name, params, inputs)
}

/// [`create`], refused before any heavy work when its [`Plan`] is over `limits`.
#[cfg(feature = "create")]
pub fn create_within(
    model: &str,
    name: &str,
    params: &serde_json::Value,
    inputs: &Inputs,
    limits: &Limits,
) -> Result<Bundle> {
    check_name(name)?;
    let m = get(model)?;
    limits.check(model, &m.plan_create(params, inputs)?)?;
    m.create(name, params, inputs)
}

/// Validates an encoding completely and returns the texture it describes, with resources of its
/// own (no cache).
pub fn load(bundle: &Bundle) -> Result<Arc<dyn Texture>> {
    load_with(bundle, &Resources::default())
}

/// [`load`], the texture sharing `resources` with the others loaded with them.
pub fn load_with(bundle: &Bundle, resources: &Resources) -> Result<Arc<dyn Texture>> {
    check_name(&bundle.manifest.name)?;
    get(&bundle.manifest.model)?.load(bundle, resources)
}

/// [`load_with`], refused before any heavy work when its [`Plan`] is over `limits`.
pub fn load_within(bundle: &Bundle, limits: &Limits, resources: &Resources) -> Result<Arc<dyn Texture>> {
    limits.check(&bundle.manifest.model, &plan(bundle)?)?;
    get(&bundle.manifest.model)?.load(bundle, resources)
}

/// Checks what loading `bundle` takes on trust ([`Model::verify`]): where a bundle from outside
/// is accepted, after it loads.
#[cfg(feature = "create")]
pub fn verify(bundle: &Bundle) -> Result<()> {
    get(&bundle.manifest.model)?.verify(bundle)
}

/// What loading `bundle` would give and cost, without loading it.
pub fn plan(bundle: &Bundle) -> Result<Plan> {
    check_name(&bundle.manifest.name)?;
    get(&bundle.manifest.model)?.plan(bundle)
}

/// Every model's demo encodings, sorted by name.
#[cfg(feature = "create")]
pub fn demos() -> Vec<Bundle> {
    let mut all: Vec<Bundle> = REGISTRY.iter().flat_map(|m| m.demos()).collect();
    all.sort_by(|a, b| a.manifest.name.cmp(&b.manifest.name));
    all
}

fn check_name(name: &str) -> Result<()> {
    let n = name.chars().count();
    if n == 0 || n > 200 || name.chars().any(char::is_control) {
        return Err(Error::param("name", "1 to 200 printable characters"));
    }
    Ok(())
}

/// The sections of `bundle` that hold input images as given, by input name: `(input, section)`
/// pairs, those present.
#[cfg(feature = "create")]
pub fn section_inputs(bundle: &Bundle, pairs: &[(&str, &str)]) -> Inputs {
    pairs
        .iter()
        .filter_map(|&(input, section)| Some((input.to_string(), bundle.section(section).ok()?.to_vec())))
        .collect()
}

/// The input image called `name`, decoded, or an error naming it.
#[cfg(feature = "create")]
pub fn input_image(inputs: &Inputs, name: &str) -> Result<crate::Rgba8Image> {
    let bytes = inputs.get(name).ok_or_else(|| Error::image(name, "missing; this model needs it"))?;
    crate::pixels::decode_png(name, bytes)
}

/// Parses a model's parameters from JSON. Only an object is accepted; a wrong type, a missing
/// or an unknown field is an [`Error::Param`] named by its full path (`layers[2].weight`).
pub fn parse_params<P: serde::de::DeserializeOwned>(params: &serde_json::Value) -> Result<P> {
    if !params.is_object() {
        return Err(Error::param("params", format!("must be a JSON object, not {}", json_kind(params))));
    }
    serde_path_to_error::deserialize(params).map_err(|e| {
        let path = e.path().to_string();
        let name = if path == "." { "params".to_string() } else { path };
        Error::param(name, e.into_inner().to_string())
    })
}

fn json_kind(v: &serde_json::Value) -> &'static str {
    match v {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::Object(_) => "an object",
    }
}

/// The JSON Schema of a model's parameter type, for [`ModelInfo::params_schema`].
#[cfg(feature = "create")]
pub fn params_schema<P: schemars::JsonSchema>() -> serde_json::Value {
    schemars::schema_for!(P).into()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn unknown_models_are_named_with_the_known_ids() {
        let Err(Error::UnknownModel { model, known }) = get("voronoi") else { panic!("`voronoi` was found") };
        assert_eq!(model, "voronoi");
        assert_eq!(known, ids().collect::<Vec<_>>().join(", "));
        assert!(known.contains("chaos-mosaic, lcm"), "{known}");
        assert!(create("voronoi", "v", &json!({}), &Inputs::new()).is_err());
    }

    #[test]
    fn every_entry_is_found_by_its_id_and_describes_itself() {
        for m in REGISTRY {
            assert_eq!(get(m.id()).unwrap().id(), m.id());
            let info = m.describe();
            assert_eq!(info.id, m.id());
            assert!(info.params_schema["properties"].is_object(), "{}: {}", m.id(), info.params_schema);
        }
        assert_eq!(*MODELS, ids().collect::<Vec<_>>());
        assert_eq!(*MODELS, ALL, "every model of vtex is in the default build, in the order of `ALL`");
    }

    /// Every model's example is small and quick: it names every input the model requires, is
    /// planned within a second to make (order-independent's `create` measures its coarse
    /// levels' calibration) and a second a tile, and `create` makes exactly what was planned.
    #[test]
    fn every_example_creates_a_small_texture_quickly() {
        let quick =
            Limits { max_resident_bytes: 64 << 20, max_tile_work: 1_000_000_000, max_build_work: 1_000_000_000 };
        for m in REGISTRY {
            let ex = m.example();
            for required in m.describe().inputs.iter().filter(|i| i.required) {
                assert!(ex.inputs.iter().any(|i| i.name == required.name), "{}: no `{}`", m.id(), required.name);
            }
            let plan = m.plan_create(&ex.params, &ex.inputs()).unwrap();
            quick.check(m.id(), &plan).unwrap_or_else(|e| panic!("{}: {e}", m.id()));
            assert!(plan.width <= 4096 && plan.height <= 4096, "{}: {}×{}", m.id(), plan.width, plan.height);
            let texture = load(&create_within(m.id(), "example", &ex.params, &ex.inputs(), &quick).unwrap()).unwrap();
            assert_eq!((texture.width(), texture.height()), (plan.width, plan.height), "{}", m.id());
        }
    }

    #[test]
    fn parameter_errors_name_the_full_path() {
        let name = |v: serde_json::Value| match parse_params::<lcm::Params>(&v) {
            Err(Error::Param { name, .. }) => name,
            other => panic!("{v}: {other:?}"),
        };
        let layer = json!({"layer": 0, "lcm": [4, 4]});
        let bad_weight = json!({"layer": 0, "lcm": [4, 4], "weight": "heavy"});
        assert_eq!(name(json!({"layers": [layer, layer, bad_weight]})), "layers[2].weight");
        assert_eq!(name(json!({"layers": [], "seed": -1})), "seed");
        assert_eq!(name(json!({"layers": [], "colour": 1})), "colour");
        assert_eq!(name(json!({"layers": [{"layer": 0, "lcm": [4, 4], "colour": 1}]})), "layers[0].colour");
        assert_eq!(name(json!([1, 2])), "params");
        assert!(parse_params::<lcm::Params>(&json!({"layers": []})).is_ok());
    }
}
