//! Fur already there: the nodes shellbake added (their `extras`), the layers it named when a
//! tool dropped those marks, and the parts they fur, so that a baked file read again is not
//! furred twice.

use serde_json::Value;

use crate::input::document::Document;

/// Whether node `n` is one shellbake added (its `extras` say so).
pub fn is_fur_node(json: &Value, n: usize) -> bool {
    json["nodes"][n]["extras"].get("shellbake").is_some()
        || json["nodes"][n]["extras"].get("shellbake_fur").is_some()
}

/// The surface a name shellbake gives a layer's node, mesh or material names: `body` of
/// `body_lod0_layer_001` or `body_layer_001`, `` of `layer_000` or `lod0_layer_000` (a plain
/// mesh's, a one-fur file's), with or
/// without the `.001` an importer appends to a repeated name; `None` for any other name.
pub(super) fn layer_owner(name: &str) -> Option<&str> {
    let name = match name.rsplit_once('.') {
        Some((stem, n)) if n.len() == 3 && n.bytes().all(|b| b.is_ascii_digit()) => stem,
        _ => name,
    };
    let (before, digits) = name.rsplit_once("layer_")?;
    if digits.len() != 3 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    if before.is_empty() {
        return Some("");
    }
    let before = before.strip_suffix('_')?;
    // a one-fur file's levels: `lod0_layer_001` (a skinned fur's, whose layer nodes are roots)
    let level = |k: &str| !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit());
    if before.strip_prefix("lod").is_some_and(level) {
        return Some("");
    }
    Some(match before.rsplit_once("_lod") {
        Some((owner, k)) if !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()) => owner,
        _ => before,
    })
}

/// Whether `name` is one shellbake gives a layer ([`layer_owner`]).
fn layer_named(name: &str) -> bool {
    layer_owner(name).is_some()
}

/// Adds to `fur` the nodes that draw shellbake's layers without its marks — named as it names
/// a layer's node or mesh, every primitive's material too — and warns: tools that drop `extras`
/// (gltfpack without `-ke`, Blender's exporter by default) turned a baked file into one whose
/// every layer would grow fur of its own (96 surfaces and 24× the triangles on the creature).
/// Returns those nodes' names and the warning.
pub(super) fn named_like_fur(
    doc: &Document,
    fur: &mut std::collections::HashSet<usize>,
) -> (Vec<String>, Option<String>) {
    let name = |list: &str, i: usize| doc.json[list][i]["name"].as_str().unwrap_or("");
    let found: Vec<usize> = (0..doc.nodes.len())
        .filter(|&n| !fur.contains(&n))
        .filter(|&n| {
            let Some(m) = doc.nodes[n].mesh else {
                return false;
            };
            (layer_named(name("nodes", n)) || layer_named(name("meshes", m)))
                && (doc.meshes[m].primitives.iter()).all(|p| {
                    p.material
                        .is_some_and(|k| layer_named(name("materials", k)))
                })
        })
        .collect();
    let Some(&first) = found.first() else {
        return (Vec::new(), None);
    };
    fur.extend(&found);
    let said = format!(
        "{}: {} node(s) draw shellbake's fur layers without its marks (their extras were \
         dropped), '{}' first: taken as fur, and their parts as furred",
        doc.path.display(),
        found.len(),
        crate::input::boundary::escape(name("nodes", first))
    );
    (
        found
            .iter()
            .map(|&n| name("nodes", n).to_string())
            .collect(),
        Some(said),
    )
}

/// The nodes shellbake added (see [`is_fur_node`]) and everything under them (a rigid part's
/// fur root holds its layer and LOD nodes).
pub(super) fn fur_subtrees(doc: &Document) -> std::collections::HashSet<usize> {
    let mut out = std::collections::HashSet::new();
    let mut stack: Vec<usize> = (0..doc.nodes.len())
        .filter(|&n| is_fur_node(&doc.json, n))
        .collect();
    while let Some(n) = stack.pop() {
        if out.insert(n) {
            stack.extend(doc.nodes[n].children.iter().copied());
            // a chunk's coarser levels (roots of the levels' scene, reached by no child link)
            let ids = &doc.json["nodes"][n]["extensions"]["MSFT_lod"]["ids"];
            let ids = ids
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(Value::as_u64);
            stack.extend(ids.map(|i| i as usize).filter(|&i| i < doc.nodes.len()));
        }
    }
    out
}

/// The (node, primitive) pairs that carry shellbake fur: those a fur node's
/// `extras.shellbake_fur` names (`node` and `primitive`, and each of `also`'s).
pub(super) fn furred_parts(doc: &Document) -> std::collections::HashSet<(usize, usize)> {
    let place = |m: &serde_json::Value| {
        Some((
            m["node"].as_u64()? as usize,
            m["primitive"].as_u64()? as usize,
        ))
    };
    (0..doc.nodes.len())
        .flat_map(|n| {
            let marker = &doc.json["nodes"][n]["extras"]["shellbake_fur"];
            // one fur over several parts names the others in `also`
            let also = marker["also"].as_array().into_iter().flatten();
            std::iter::once(marker).chain(also).filter_map(place)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layer_names_name_their_surface() {
        assert_eq!(layer_owner("body_lod0_layer_001"), Some("body"));
        assert_eq!(layer_owner("lod0_layer_001"), Some(""));
        assert_eq!(layer_owner("lod12_layer_001.002"), Some(""));
        assert_eq!(layer_owner("critter_0_1_layer_031"), Some("critter_0_1"));
        assert_eq!(layer_owner("my_lodge_layer_002.001"), Some("my_lodge"));
        assert_eq!(layer_owner("layer_000"), Some(""));
        for other in [
            "body",
            "layer_1",
            "body_layer_0001",
            "bodylayer_001",
            "layer_abc",
        ] {
            assert_eq!(layer_owner(other), None, "{other}");
        }
    }
}
