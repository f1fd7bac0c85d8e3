//! The command line: `vtex serve | create | models | render | info | export-web | health`.

use crate::catalogue;
use crate::config::ServeConfig;
use crate::encode::{self, Format};
use crate::store::{self, Bounds, Entry, Store};
use anyhow::{anyhow, bail, Context};
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};
use vtex_synth::models::{self, Inputs};
use vtex_synth::{Region, Resources};

#[derive(Parser, Debug)]
#[command(name = "vtex", version, about = "Virtual textures: store compact encodings, serve any tile at any level.")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Serve the HTTP API and the viewer.
    Serve(Box<ServeConfig>),
    /// Make an encoding from model parameters and input images; prints its id.
    Create(CreateArgs),
    /// List the models: parameters (JSON Schema), input images and an example of each.
    Models(ModelsArgs),
    /// Render a region of a texture at a level to an image file.
    Render(RenderArgs),
    /// Print a texture's info as JSON, or every texture in the data directory.
    Info(InfoArgs),
    /// Write a folder any static file server can host: the viewer, the synthesis module and the
    /// texture's encoding; the browser synthesizes every tile (no vtex needed).
    ExportWeb(ExportWebArgs),
    /// Ask a running `vtex serve` whether it is ready (`GET /readyz`); exit status 1 if not.
    Health(crate::probe::HealthArgs),
}

#[derive(Args, Debug)]
pub struct CreateArgs {
    #[arg(long, help = model_help())]
    pub model: String,
    /// Display name.
    #[arg(long)]
    pub name: String,
    /// Model parameters: JSON text, or `@file.json` (their schema and an example: `vtex models MODEL`).
    #[arg(long, default_value = "{}")]
    pub params: String,
    /// An input image, `NAME=PATH.png` (e.g. `sample=stones.png`); repeatable.
    #[arg(long = "input", value_name = "NAME=PATH")]
    pub inputs: Vec<String>,
    /// Store the bundle in this data directory (atomically).
    #[arg(long, env = "VTEX_DATA_DIR", default_value = "./vtex-data")]
    pub data_dir: PathBuf,
    /// Write the bundle to this file instead of the data directory.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct ModelsArgs {
    /// One model's id; every model when absent.
    pub model: Option<String>,
    /// Print the JSON document `GET /api/v1/models[/{id}]` answers.
    #[arg(long)]
    pub json: bool,
    /// Write the examples' input images into this directory, as `<model>-<input>.png`.
    #[arg(long, value_name = "DIR")]
    pub example_dir: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A texture id in the data directory, or the path of a `.vtex` bundle.
    pub texture: String,
    #[arg(long, env = "VTEX_DATA_DIR", default_value = "./vtex-data")]
    pub data_dir: PathBuf,
    #[arg(long, default_value_t = 0)]
    pub level: u32,
    #[arg(long, default_value_t = 0, allow_hyphen_values = true)]
    pub x: i64,
    #[arg(long, default_value_t = 0, allow_hyphen_values = true)]
    pub y: i64,
    #[arg(long, default_value_t = 256)]
    pub width: u32,
    #[arg(long, default_value_t = 256)]
    pub height: u32,
    #[arg(long, default_value_t = 0)]
    pub frame: u32,
    /// Output file; its extension picks the format (png, webp, jpg, rgba).
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// A texture id in the data directory, or the path of a `.vtex` bundle; all when absent.
    pub texture: Option<String>,
    #[arg(long, env = "VTEX_DATA_DIR", default_value = "./vtex-data")]
    pub data_dir: PathBuf,
    #[arg(long, env = "VTEX_TILE_SIZE", default_value_t = 256)]
    pub tile_size: u32,
}

#[derive(Args, Debug)]
pub struct ExportWebArgs {
    /// A texture id in the data directory, or the path of a `.vtex` bundle.
    pub texture: String,
    /// The folder to write; it must not exist or be empty.
    pub dir: PathBuf,
    #[arg(long, env = "VTEX_DATA_DIR", default_value = "./vtex-data")]
    pub data_dir: PathBuf,
    /// The built viewer, with its synthesis modules (`vtex_synth_<model>.wasm`).
    #[arg(long, env = "VTEX_WEB_DIR", default_value = "client-web/dist")]
    pub web_dir: PathBuf,
    /// Tile side in pixels the viewer asks for.
    #[arg(long, env = "VTEX_TILE_SIZE", default_value_t = 256)]
    pub tile_size: u32,
}

/// `--model`'s help: the ids of the registered models, read from the registry so it never lags.
fn model_help() -> String {
    let ids: Vec<&str> = models::ids().collect();
    format!("Model id: {} (their parameters and examples: `vtex models`)", ids.join(", "))
}

/// Loads and validates a texture named by id (in `data_dir`) or by path.
fn open_texture(texture: &str, data_dir: &Path, tile_size: u32) -> anyhow::Result<Entry> {
    Ok(open_texture_bytes(texture, data_dir, tile_size)?.0)
}

/// [`open_texture`], and its bundle's bytes.
fn open_texture_bytes(texture: &str, data_dir: &Path, tile_size: u32) -> anyhow::Result<(Entry, Vec<u8>)> {
    let by_id = data_dir.join(format!("{texture}.{}", store::BUNDLE_EXT));
    let path = if vtex_synth::bundle::is_valid_id(texture) && by_id.is_file() { by_id } else { PathBuf::from(texture) };
    let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
    let entry = Entry::from_bytes(&bytes, tile_size).with_context(|| format!("loading {}", path.display()))?;
    Ok((entry, bytes))
}

pub fn create(args: CreateArgs) -> anyhow::Result<()> {
    let params_text = match args.params.strip_prefix('@') {
        Some(file) => std::fs::read_to_string(file).with_context(|| format!("reading params file {file}"))?,
        None => args.params.clone(),
    };
    let params: serde_json::Value = serde_json::from_str(&params_text).context("params are not valid JSON")?;
    let mut inputs = Inputs::new();
    for spec in &args.inputs {
        let (name, path) = spec.split_once('=').ok_or_else(|| anyhow!("--input `{spec}`: expected NAME=PATH"))?;
        let bytes = std::fs::read(path).with_context(|| format!("reading input `{name}` from {path}"))?;
        inputs.insert(name.to_string(), bytes);
    }
    let bundle = models::create(&args.model, &args.name, &params, &inputs)?;
    let bytes = bundle.to_bytes();
    let id = vtex_synth::bundle::id_of(&bytes);
    match &args.out {
        Some(out) => {
            // Validate exactly as the server would before writing anything.
            Entry::from_bytes(&bytes, 256)?;
            let dir = out.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
            store::write_atomic(dir, out, &bytes).with_context(|| format!("writing {}", out.display()))?;
        }
        None => {
            std::fs::create_dir_all(&args.data_dir)?;
            let (store, _) = Store::open(&args.data_dir, Bounds::unbounded(256), Resources::default(), false)?;
            store.put_made(bytes)?;
        }
    }
    println!("{id}");
    Ok(())
}

pub fn models(args: ModelsArgs) -> anyhow::Result<()> {
    let docs = match &args.model {
        Some(id) => vec![catalogue::one(id).map_err(|e| anyhow!("{e}"))?],
        None => catalogue::list().models,
    };
    if let Some(dir) = &args.example_dir {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for doc in &docs {
            for name in doc.example.inputs.keys() {
                let path = dir.join(example_file(&doc.id, name));
                let png = catalogue::example_input(&doc.id, name).map_err(|e| anyhow!("{e}"))?;
                std::fs::write(&path, png).with_context(|| format!("writing {}", path.display()))?;
            }
        }
    }
    if args.json {
        let out = match &args.model {
            Some(_) => serde_json::to_string_pretty(&docs[0])?,
            None => serde_json::to_string_pretty(&catalogue::ModelList { models: docs })?,
        };
        println!("{out}");
        return Ok(());
    }
    let dir = args.example_dir.as_deref().unwrap_or(Path::new("."));
    for doc in &docs {
        println!("{}", describe_model(doc, dir));
    }
    if args.example_dir.is_none() && docs.iter().any(|d| !d.example.inputs.is_empty()) {
        println!("Write the examples' input images with `vtex models --example-dir DIR`.");
    }
    Ok(())
}

/// The file `vtex models --example-dir` writes input `name` of model `id`'s example to.
fn example_file(id: &str, name: &str) -> String {
    format!("{id}-{name}.png")
}

/// One model for people: what it is, its parameters and inputs, and its example as a
/// `vtex create` command whose inputs are in `dir`.
fn describe_model(doc: &catalogue::ModelDoc, dir: &Path) -> String {
    let schema = &doc.params_schema;
    let required: Vec<&str> = schema["required"].as_array().into_iter().flatten().filter_map(|v| v.as_str()).collect();
    let params: Vec<String> = schema["properties"]
        .as_object()
        .into_iter()
        .flatten()
        .map(|(k, _)| if required.contains(&k.as_str()) { format!("{k} (required)") } else { k.clone() })
        .collect();
    let mut out = format!("{} — {}\n  {}\n  {}\n", doc.id, doc.title, doc.paper, doc.summary);
    out += &format!("  params: {}\n", params.join(", "));
    for i in &doc.inputs {
        out += &format!("  input {}{}: {}\n", i.name, if i.required { " (required)" } else { "" }, i.what);
    }
    let params = serde_json::to_string(&doc.example.params).expect("JSON values serialize");
    let mut command = format!("vtex create --model {} --name \"{} example\" --params '{params}'", doc.id, doc.id);
    for name in doc.example.inputs.keys() {
        command += &format!(" --input {name}={}", dir.join(example_file(&doc.id, name)).display());
    }
    out += &format!("  example: {command}\n");
    out
}

pub fn render(args: RenderArgs) -> anyhow::Result<()> {
    let ext = args.out.extension().and_then(|e| e.to_str()).unwrap_or("");
    let Some(format) = Format::parse(ext) else { bail!("output extension `{ext}`; {}", Format::EXPECTED) };
    let entry = open_texture(&args.texture, &args.data_dir, 256)?;
    let region = Region::new(args.level, args.x, args.y, args.width, args.height).at_frame(args.frame);
    let img = vtex_synth::texture::render_image(&*entry.texture, &region)?;
    let bytes = encode::encode(img, format).map_err(anyhow::Error::msg)?;
    std::fs::write(&args.out, bytes).with_context(|| format!("writing {}", args.out.display()))?;
    Ok(())
}

pub fn info(args: InfoArgs) -> anyhow::Result<()> {
    let out = match &args.texture {
        Some(t) => serde_json::to_string_pretty(&open_texture(t, &args.data_dir, args.tile_size)?.info())?,
        None => {
            let (store, report) =
                Store::open(&args.data_dir, Bounds::unbounded(args.tile_size), Resources::default(), false)?;
            for (path, why) in report.rejected {
                eprintln!("skipping {path}: {why}");
            }
            let all: Vec<_> = store.list().iter().map(|e| e.info()).collect();
            serde_json::to_string_pretty(&serde_json::json!({ "textures": all }))?
        }
    };
    println!("{out}");
    Ok(())
}

pub fn export_web(args: ExportWebArgs) -> anyhow::Result<()> {
    if !crate::config::TILE_SIZES.contains(&args.tile_size) {
        let sizes = crate::config::TILE_SIZES;
        bail!("--tile-size {}: from {} to {}", args.tile_size, sizes.start(), sizes.end());
    }
    let (entry, bundle) = open_texture_bytes(&args.texture, &args.data_dir, args.tile_size)?;
    let written = crate::export::export_web(&entry, &bundle, &args.web_dir, &args.dir)?;
    println!(
        "{}: {} files, {} bytes ({} the encoding); serve it with any static file server, e.g. \
         python3 -m http.server -d {}",
        args.dir.display(),
        written.files,
        written.bytes,
        bundle.len(),
        args.dir.display()
    );
    Ok(())
}
