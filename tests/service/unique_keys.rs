//! The checker every helper reads the API's answers with (`support::unique_keys`): a key twice
//! in one object is caught, at the top and nested in objects and arrays; equal keys in different
//! objects and well-formed documents pass unchanged.

use crate::support::unique_keys::parse_unique_keys;
use serde_json::json;

#[test]
fn a_repeated_key_is_caught_at_any_depth() {
    for (text, key, at) in [
        (
            r#"{"dof": 1, "variance_factor": 0.9, "dof": 1}"#,
            "dof",
            "/",
        ),
        (r#"{"epoch": {"id": 1, "id": 2}}"#, "id", "/epoch"),
        (
            r#"{"items": [{"a": 1}, {"b": {"c": [1, {"d": 1, "d": 2}]}}]}"#,
            "d",
            "/items/1/b/c/1",
        ),
        (r#"[{"x": null, "x": null}]"#, "x", "/0"),
    ] {
        let e = parse_unique_keys(text).unwrap_err();
        assert!(
            e.contains(&format!(
                "key \"{key}\" appears twice in the object at {at}"
            )),
            "{text}: {e}"
        );
    }
}

#[test]
fn well_formed_documents_parse_as_serde_json_reads_them() {
    for text in [
        r#"{"a": 1, "b": {"a": 2}, "c": [{"a": 3}, {"a": 4}], "d": null, "e": -1.5e-7, "f": "x"}"#,
        r#"[1, 2.5, true, false, null, "s", [], {}]"#,
        r#""text""#,
        "18446744073709551615",
    ] {
        let ours = parse_unique_keys(text).unwrap();
        let theirs: serde_json::Value = serde_json::from_str(text).unwrap();
        assert_eq!(ours, theirs, "{text}");
    }
    assert_eq!(
        parse_unique_keys(r#"{"a/b": {"c~": 1}}"#).unwrap(),
        json!({"a/b": {"c~": 1}})
    );
    // Not JSON, or JSON followed by more text: an error, as serde_json gives.
    assert!(parse_unique_keys("{\"a\": 1} x").is_err());
    assert!(parse_unique_keys("{\"a\": }").is_err());
}
