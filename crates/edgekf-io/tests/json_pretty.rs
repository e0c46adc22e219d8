//! `to_json_pretty`: the same values as serde_json's pretty printer, matrices one row per line.

use serde_json::{json, Value};

#[test]
fn compact_rows_parse_back_to_the_same_values() {
    let v = json!({
        "schema": "edgekf.scenario/1",
        "dim": 2,
        "seed": u64::MAX,
        "config": [[0.1, -2.5e-300], [1.0 / 3.0, 7.0]],
        "empty": [],
        "nested": { "a": [1, "x", null, true], "b": {} },
        "mixed": [[1.0], 2.0]
    });
    let text = edgekf_io::to_json_pretty(&v).unwrap();
    let back: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(back, v);
    // Bit-exact floats, keys in their order.
    assert_eq!(
        back["config"][1][0].as_f64().unwrap().to_bits(),
        (1.0f64 / 3.0).to_bits()
    );
    let keys: Vec<&String> = back.as_object().unwrap().keys().collect();
    assert_eq!(keys[0], "schema");
    // A matrix: one row per line.
    assert!(text.contains("\n    [0.1, -2.5e-300],\n"), "{text}");
    assert!(text.contains("\"a\": [1, \"x\", null, true]"), "{text}");
    assert!(text.contains("\"empty\": []"), "{text}");
}

#[test]
fn a_resolved_scenario_is_smaller_and_parses_to_the_same_spec() {
    let sc = edgekf_io::load_scenario(
        "min.toml",
        "name = \"min\"\nestimators = [\"rkf\"]\n[framework]\npreset = \"hexagon\"\n",
        None,
    )
    .unwrap();
    let ours = edgekf_io::scenario_json(&sc).unwrap();
    let serde = serde_json::to_string_pretty(&sc.to_resolved()).unwrap();
    let a: Value = serde_json::from_str(&ours).unwrap();
    let b: Value = serde_json::from_str(&serde).unwrap();
    assert_eq!(a, b);
    assert!(
        ours.len() * 4 < serde.len() * 3,
        "{} vs {}",
        ours.len(),
        serde.len()
    );
}
