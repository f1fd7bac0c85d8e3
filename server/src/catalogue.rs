//! The model catalogue: every registered model with the JSON Schema of its parameters, its input
//! images and an example that creates a small texture through the upload path. The API serves it
//! (`GET /api/v1/models[/{id}]`, the example's input images) and so does `vtex models`.
//! Everything in it comes from [`vtex_synth::models::REGISTRY`]; the server knows no model by
//! name.

use crate::engine::{echo, Error};
use serde::Serialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::sync::LazyLock;
use vtex_synth::models::{self, Example, Model};

/// `GET /api/v1/models`.
#[derive(Clone, Debug, Serialize, utoipa::ToSchema)]
pub struct ModelList {
    pub models: Vec<ModelDoc>,
}

/// One model: what it is, what `create` takes, and an example of it.
#[derive(Clone, Debug, Serialize, utoipa::ToSchema)]
pub struct ModelDoc {
    /// The id uploads and bundles name (`model` of a multipart upload).
    pub id: String,
    pub title: String,
    /// The publication the model implements.
    pub paper: String,
    pub summary: String,
    /// JSON Schema (draft 2020-12) of the `params` of an upload.
    #[schema(value_type = Object)]
    pub params_schema: Value,
    /// The input images an upload may carry, as multipart fields of these names.
    pub inputs: Vec<InputDoc>,
    pub example: ExampleDoc,
}

/// One input image of a model.
#[derive(Clone, Debug, Serialize, utoipa::ToSchema)]
pub struct InputDoc {
    /// The multipart field name; `*` stands for any name the parameters give an input.
    pub name: String,
    pub required: bool,
    pub what: String,
}

/// Parameters and input images that create a small texture of the model quickly when posted
/// as a multipart upload (`model`, `params`, one field per input).
#[derive(Clone, Debug, Serialize, utoipa::ToSchema)]
pub struct ExampleDoc {
    #[schema(value_type = Object)]
    pub params: Value,
    /// Every input image `params` needs, by multipart field name.
    pub inputs: BTreeMap<String, ExampleInputDoc>,
}

/// Where to get an example's input image.
#[derive(Clone, Debug, Serialize, utoipa::ToSchema)]
pub struct ExampleInputDoc {
    /// What the image is and how vtex drew it.
    pub what: String,
    /// The PNG: its absolute URL over HTTP (made like every absolute URL, `api::origin::Origin`);
    /// a path from the server's root in `vtex models`.
    pub href: String,
}

/// The route of an example's input image.
pub const EXAMPLE_INPUT: &str = "/api/v1/models/{id}/example/{file}";

/// One model's entry: its document and its example's images.
struct Entry {
    doc: ModelDoc,
    example: Example,
}

/// Built once: the examples draw their input images.
static CATALOGUE: LazyLock<Vec<Entry>> = LazyLock::new(|| models::REGISTRY.iter().map(|m| entry(*m)).collect());

fn entry(m: &dyn Model) -> Entry {
    let info = m.describe();
    let example = m.example();
    let inputs = example
        .inputs
        .iter()
        .map(|i| {
            let href = EXAMPLE_INPUT.replace("{id}", info.id).replace("{file}", &format!("{}.png", i.name));
            (i.name.clone(), ExampleInputDoc { what: i.what.clone(), href })
        })
        .collect();
    let doc = ModelDoc {
        id: info.id.into(),
        title: info.title.into(),
        paper: info.paper.into(),
        summary: info.summary.into(),
        params_schema: info.params_schema,
        inputs: info
            .inputs
            .iter()
            .map(|i| InputDoc { name: i.name.into(), required: i.required, what: i.what.into() })
            .collect(),
        example: ExampleDoc { params: example.params.clone(), inputs },
    };
    Entry { doc, example }
}

/// Every model's document, in registry order.
pub fn list() -> ModelList {
    ModelList { models: CATALOGUE.iter().map(|e| e.doc.clone()).collect() }
}

/// The catalogue entry of model `id`, or an error naming the known models.
fn find(id: &str) -> Result<&'static Entry, Error> {
    CATALOGUE.iter().find(|e| e.doc.id == id).ok_or_else(|| {
        let known: Vec<&str> = models::ids().collect();
        Error::Missing(format!("no model `{}`; the models are {}", echo(id), known.join(", ")))
    })
}

/// The document of model `id`.
pub fn one(id: &str) -> Result<ModelDoc, Error> {
    Ok(find(id)?.doc.clone())
}

/// The PNG of input `name` of model `id`'s example.
pub fn example_input(id: &str, name: &str) -> Result<&'static [u8], Error> {
    let entry = find(id)?;
    let input = entry.example.inputs.iter().find(|i| i.name == name).ok_or_else(|| {
        let names: Vec<&str> = entry.example.inputs.iter().map(|i| i.name.as_str()).collect();
        let names = if names.is_empty() { "none".to_string() } else { names.join(", ") };
        Error::Missing(format!("model `{id}`'s example has no input `{}`; its inputs: {names}", echo(name)))
    })?;
    Ok(&input.png)
}
