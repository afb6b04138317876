//! Model files (`kinpost fit` output) are read strictly: a key given twice,
//! an unknown (misspelt) key and a model without `axes` are refused with
//! file:line:col, instead of being dropped or compensating nothing.

use kinpost::geometric::model::ErrorModel;

const GOOD: &str = r#"{
  "format": "kinpost-error-model",
  "version": 1,
  "_note": "comment keys are ignored",
  "meta": {"description": "test"},
  "axes": [
    {"axis": "B", "rotary": true, "position_unit": "deg", "columns": [
      {"name": "EBB", "component": "ey", "unit": "urad", "degree": 1,
       "knots": [0, 0, 90, 90], "coefficients": [0, 10]}]}
  ],
  "fixed": [{"name": "squareness XZ", "after_joint": "X", "motion": [0, 0, 0, 0, 1e-5, 0]}]
}
"#;

fn err(text: &str) -> String {
    ErrorModel::from_json_str(text, "m.json")
        .expect_err("the model should be refused")
        .to_string()
}

/// `m.json:LINE:COL: ` of the `nth` occurrence of `marker`.
fn at(text: &str, marker: &str, nth: usize) -> String {
    let off = text.match_indices(marker).nth(nth).unwrap().0;
    let before = &text[..off];
    let line = before.matches('\n').count() + 1;
    let col = off - before.rfind('\n').map_or(0, |p| p + 1) + 1;
    format!("m.json:{line}:{col}: ")
}

#[test]
fn the_good_model_loads() {
    let m = ErrorModel::from_json_str(GOOD, "m.json").unwrap();
    assert_eq!(m.axes.len(), 1);
    assert_eq!(m.fixed.len(), 1);
}

#[test]
fn duplicate_keys_are_refused() {
    let text = GOOD.replace("\"degree\": 1,", "\"degree\": 1, \"degree\": 3,");
    let e = err(&text);
    assert!(e.starts_with(&at(&text, "\"degree\"", 1)), "{e}");
    assert!(e.contains("duplicate key `degree`"), "{e}");
}

#[test]
fn unknown_keys_are_refused_with_the_known_ones() {
    for (from, to, what) in [
        (
            "\"fixed\"",
            "\"fixd\"",
            "unknown key `fixd` in the error model",
        ),
        (
            "\"position_unit\"",
            "\"position_units\"",
            "unknown key `position_units` in axes[0]",
        ),
        (
            "\"coefficients\"",
            "\"coeficients\"",
            "unknown key `coeficients` in axes[0].columns[0]",
        ),
        (
            "\"after_joint\"",
            "\"after\"",
            "unknown key `after` in fixed[0]",
        ),
        (
            "\"description\"",
            "\"descr\"",
            "unknown key `descr` in `meta`",
        ),
        (
            "\"description\": \"test\"",
            "\"fit\": {\"extrap\": 1}",
            "unknown key `extrap` in `meta.fit`",
        ),
    ] {
        let text = GOOD.replacen(from, to, 1);
        let e = err(&text);
        let key = &what[what.find('`').unwrap() + 1..];
        let key = format!("\"{}\"", &key[..key.find('`').unwrap()]);
        assert!(e.starts_with(&at(&text, &key, 0)), "{e}");
        assert!(e.contains(what), "{e}");
        assert!(e.contains("expected one of `"), "{e}");
    }
}

#[test]
fn a_model_without_axes_is_refused() {
    let text = "{\"format\": \"kinpost-error-model\", \"version\": 1, \"meta\": {}}";
    let e = err(text);
    assert!(e.starts_with("m.json:1:1: "), "{e}");
    assert!(
        e.contains("no `axes`") && e.contains("compensate nothing"),
        "{e}"
    );
    // An explicit empty list with fixed errors is a model.
    let text = "{\"format\": \"kinpost-error-model\", \"version\": 1, \"axes\": [], \"fixed\": [{\"name\": \"sq\", \"after_joint\": null, \"motion\": [0, 0, 0, 0, 1e-5, 0]}]}";
    assert_eq!(
        ErrorModel::from_json_str(text, "m.json")
            .unwrap()
            .fixed
            .len(),
        1
    );
}
