//! Making an encoding again with changed parameters (the server's PATCH): by its model's own
//! `create`, from the parameters as the user gave them (the manifest's `params`, never the
//! fields `create` derived, which are kept apart) and the input images the bundle holds, so
//! that everything the parameters derive — LCMs, σ tables, block sequences, value ranges —
//! follows them: the result is exactly what a fresh `create` of the patched params makes.

use super::{check_name, create_within, get, Inputs, Limits};
use crate::bundle::{Bundle, Manifest};
use crate::{Error, Result};
use serde_json::Value;

/// `bundle` made again as `name` with `params` (its manifest's params, patched), within
/// `limits`. With its own params it is only renamed. Otherwise its model's `create` makes it
/// from `params` and the inputs it recovers from the bundle ([`super::Model::inputs_of`]) —
/// but only if `create` makes the very same derived fields and sections from the bundle's
/// own params: a bundle uploaded with parts made elsewhere (a hand-drawn LCM, an edited block
/// sequence or range) cannot be remade, and that is refused, naming the first field that
/// changed and the part that was not made by its params.
pub fn remake_within(bundle: &Bundle, name: &str, params: &Value, limits: &Limits) -> Result<Bundle> {
    check_name(name)?;
    let old = &bundle.manifest;
    if *params == old.params {
        let manifest = Manifest { name: name.into(), ..old.clone() };
        return Ok(Bundle { manifest, sections: bundle.sections.clone() });
    }
    let changed = first_difference(&old.params, params, String::new());
    let refuse = |why: String| {
        Error::param(&changed, format!("cannot be changed on this encoding: {why}; edit and upload the bundle instead"))
    };
    let model = get(&old.model)?;
    let inputs: Inputs =
        model.inputs_of(bundle).map_err(|e| refuse(format!("its input images cannot be recovered ({e})")))?;
    let again = create_within(&old.model, &old.name, &old.params, &inputs, limits).map_err(|e| match e {
        Error::TooCostly { .. } => e,
        e => refuse(format!("its own params do not make it ({e})")),
    })?;
    if let Some(part) = not_made(bundle, &again, &inputs) {
        return Err(refuse(format!("its {part} is not what its params make (it was uploaded, not created)")));
    }
    create_within(&old.model, name, params, &inputs, limits)
}

/// The first part of `bundle` that `again` — made by `create` from the bundle's own params
/// and `inputs` — does not hold alike: a derived field, or a section. Sections that hold an
/// input image exactly as given are not compared: `create` stores the same pixels in its own
/// PNG encoding; nor is a cached section ([`super::Model::cached_sections`]) that the bundle,
/// stored before it existed, lacks.
fn not_made(bundle: &Bundle, again: &Bundle, inputs: &Inputs) -> Option<String> {
    let made = &again.manifest.derived;
    if let Some((k, _)) = bundle.manifest.derived.iter().find(|(k, v)| made.get(*k) != Some(*v)) {
        return Some(format!("derived `{k}`"));
    }
    let given = |data: &[u8]| inputs.values().any(|png| png == data);
    let cached = get(&bundle.manifest.model).map_or(&[][..], |m| m.cached_sections());
    bundle
        .sections
        .iter()
        .chain(&again.sections)
        .map(|s| s.name.as_str())
        .find(|name| match (bundle.section(name).ok(), again.section(name).ok()) {
            (Some(ours), Some(made)) => ours != made && !given(ours),
            // Derived data stored since the bundle was: it renders the same without.
            (None, Some(_)) => !cached.contains(name),
            _ => true,
        })
        .map(|name| format!("section `{name}`"))
}

/// RFC 7396 JSON merge patch: objects merge recursively, `null` deletes, anything else
/// replaces (an array is replaced whole).
pub fn merge_patch(target: &mut Value, patch: &Value) {
    let Value::Object(patch) = patch else {
        *target = patch.clone();
        return;
    };
    if !target.is_object() {
        *target = Value::Object(Default::default());
    }
    let map = target.as_object_mut().expect("made an object above");
    for (k, v) in patch {
        if v.is_null() {
            map.remove(k);
        } else {
            merge_patch(map.entry(k.clone()).or_insert(Value::Null), v);
        }
    }
}

/// The path (`layers[0].table`, `seed`) of the first value that differs between `a` and `b`,
/// in the style of parameter errors; `params` when the whole value differs at the top.
fn first_difference(a: &Value, b: &Value, at: String) -> String {
    let field = |key: &str| if at.is_empty() { key.to_string() } else { format!("{at}.{key}") };
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter()
                .find(|k| x.get(*k) != y.get(*k))
                .map(|k| match (x.get(k), y.get(k)) {
                    (Some(u), Some(v)) => first_difference(u, v, field(k)),
                    _ => field(k),
                })
                .unwrap_or(at)
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => {
            let i = x.iter().zip(y).position(|(u, v)| u != v);
            i.map(|i| first_difference(&x[i], &y[i], format!("{at}[{i}]"))).unwrap_or(at)
        }
        _ if at.is_empty() => "params".into(),
        _ => at,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn merge_patch_follows_rfc7396() {
        // The example of RFC 7396 §3.
        let mut doc = json!({"title": "Goodbye!", "author": {"givenName": "John", "familyName": "Doe"},
                             "tags": ["example", "sample"], "content": "This will be unchanged"});
        let patch = json!({"title": "Hello!", "phoneNumber": "+01-123-456-7890",
                           "author": {"familyName": null}, "tags": ["example"]});
        merge_patch(&mut doc, &patch);
        assert_eq!(
            doc,
            json!({"title": "Hello!", "author": {"givenName": "John"}, "tags": ["example"],
                   "content": "This will be unchanged", "phoneNumber": "+01-123-456-7890"})
        );
        let mut scalar = json!(1);
        merge_patch(&mut scalar, &json!({"a": {"b": null, "c": 2}}));
        assert_eq!(scalar, json!({"a": {"c": 2}}));
    }

    #[test]
    fn the_first_difference_is_named_by_its_path() {
        let a = json!({"seed": 1, "layers": [{"weight": 1.0, "table": {"width": 2}}, {"weight": 0.5}]});
        let path = |b: Value| first_difference(&a, &b, String::new());
        let mut b = a.clone();
        b["layers"][1]["weight"] = json!(0.4);
        assert_eq!(path(b), "layers[1].weight");
        let mut b = a.clone();
        b["layers"][0]["table"]["width"] = json!(1);
        assert_eq!(path(b.clone()), "layers[0].table.width");
        b["seed"] = json!(2);
        assert_eq!(path(b), "layers[0].table.width", "keys in sorted order");
        let mut b = a.clone();
        b["seed"] = json!(7);
        assert_eq!(path(b), "seed");
        let mut b = a.clone();
        b["layers"].as_array_mut().unwrap().pop();
        assert_eq!(path(b), "layers");
        let mut b = a.clone();
        b["tiles"] = json!([2, 2]);
        assert_eq!(path(b), "tiles");
        assert_eq!(path(json!([1])), "params");
    }
}
