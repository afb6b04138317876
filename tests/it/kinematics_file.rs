//! Machine-file validation: every error names file:line:col of the
//! offending text and says what was expected.

use kinpost::Error;
use kinpost::machine::{JointKind, Machine, RotaryMode};

/// A valid machine file; the tests below break one thing at a time.
const GOOD: &str = r#"{
  "name": "test-xzbc",
  "description": "test machine",
  "chain": [
    {"revolute": {"name": "C", "axis": [0, 0, -1]}},
    {"prismatic": {"name": "X", "axis": [1, 0, 0]}},
    {"prismatic": {"name": "Z", "axis": [0, 0, 1]}},
    {"revolute": {"name": "B", "axis": [0, 1, 0]}},
    {"translate": [0, 0, -20]}
  ],
  "axes": {
    "X": {"min": -100, "max": 100, "decimals": 4},
    "Z": {"min": -100, "max": 100},
    "B": {"min": -90, "max": 90},
    "C": {"rotary": "continuous"}
  },
  "output_order": ["X", "Z", "B", "C"]
}
"#;

/// 1-based line and column of the `nth` (0-based) occurrence of `marker`
/// in `text`, plus `shift` bytes.
fn position(text: &str, marker: &str, nth: usize, shift: usize) -> (usize, usize) {
    let offset = text
        .match_indices(marker)
        .nth(nth)
        .unwrap_or_else(|| panic!("marker {marker} not found"))
        .0
        + shift;
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let col = offset - before.rfind('\n').map_or(0, |p| p + 1) + 1;
    (line, col)
}

/// Replaces the first occurrence of `from` in GOOD by `to`.
fn broken(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "{from}");
    GOOD.replacen(from, to, 1)
}

/// Parses `text` expecting an error at the `nth` occurrence of `marker`
/// (+ `shift` bytes) whose message contains `words`.
fn expect_error(text: &str, marker: &str, nth: usize, shift: usize, words: &str) {
    let err = Machine::from_json_str(text, "m.json").expect_err("the file should be rejected");
    let (line, col) = position(text, marker, nth, shift);
    let msg = err.to_string();
    assert!(
        msg.starts_with(&format!("m.json:{line}:{col}: ")),
        "expected m.json:{line}:{col}, got: {msg}"
    );
    assert!(msg.contains(words), "message lacks {words:?}: {msg}");
    assert!(matches!(err, Error::Input { .. }));
    assert_eq!(err.exit_code(), kinpost::error::exit::INPUT);
}

#[test]
fn the_good_file_loads() {
    let m = Machine::from_json_str(GOOD, "m.json").unwrap();
    assert_eq!(m.name, "test-xzbc");
    assert_eq!(
        m.axes.iter().map(|a| a.name.as_str()).collect::<Vec<_>>(),
        ["X", "Z", "B", "C"]
    );
    let c = m.axis("c").unwrap();
    assert_eq!(
        (c.joint, c.kind, c.rotary),
        (0, JointKind::Revolute, RotaryMode::Continuous)
    );
    assert_eq!(m.axis("B").unwrap().min, Some(-90.0));
    assert_eq!(m.axis("Z").unwrap().decimals, 4);
}

#[test]
fn syntax_error_is_located_by_serde() {
    let text = broken(
        "\"description\": \"test machine\",",
        "\"description\": \"test machine\"",
    );
    // serde_json reports the token after the missing comma.
    expect_error(&text, "\"chain\"", 0, 0, "not valid JSON");
}

#[test]
fn nan_is_a_syntax_error() {
    let text = broken("\"axis\": [1, 0, 0]", "\"axis\": [NaN, 0, 0]");
    expect_error(&text, "NaN", 0, 0, "not valid JSON");
}

#[test]
fn overflowing_number_is_rejected() {
    let text = broken(
        "\"min\": -100, \"max\": 100, \"decimals\": 4",
        "\"min\": -1e999, \"max\": 100",
    );
    let err = Machine::from_json_str(&text, "m.json")
        .unwrap_err()
        .to_string();
    let (line, _) = position(&text, "-1e999", 0, 0);
    assert!(err.starts_with(&format!("m.json:{line}:")), "{err}");
}

#[test]
fn unknown_element_kind_points_at_the_key() {
    let text = broken(
        "{\"revolute\": {\"name\": \"B\"",
        "{\"revolut\": {\"name\": \"B\"",
    );
    expect_error(
        &text,
        "\"revolut\"",
        0,
        0,
        "unknown chain element kind \"revolut\"",
    );
}

#[test]
fn unknown_element_type_points_at_the_value() {
    let text = broken(
        "{\"prismatic\": {\"name\": \"Z\", \"axis\": [0, 0, 1]}}",
        "{\"type\": \"prismatik\", \"name\": \"Z\", \"axis\": [0, 0, 1]}",
    );
    expect_error(
        &text,
        "\"prismatik\"",
        0,
        0,
        "expected \"revolute\", \"prismatic\", \"translate\" or \"rotate\"",
    );
}

#[test]
fn element_with_two_kinds_is_rejected() {
    let text = broken(
        "{\"translate\": [0, 0, -20]}",
        "{\"translate\": [0, 0, -20], \"rotate\": {}}",
    );
    expect_error(&text, "{\"translate\"", 0, 0, "exactly one of the keys");
}

#[test]
fn zero_axis_vector() {
    let text = broken("\"axis\": [0, 1, 0]", "\"axis\": [0, 0, 0]");
    expect_error(&text, "[0, 0, 0]", 0, 0, "zero vector");
}

#[test]
fn axis_with_two_components() {
    let text = broken("{\"translate\": [0, 0, -20]}", "{\"translate\": [0, -20]}");
    expect_error(
        &text,
        "[0, -20]",
        0,
        0,
        "expected the translation (mm) as [x, y, z]",
    );
}

#[test]
fn duplicate_joint_names() {
    let text = broken("\"name\": \"B\"", "\"name\": \"x\"");
    expect_error(&text, "\"x\"", 0, 0, "duplicate joint name \"x\"");
}

#[test]
fn joint_name_must_be_an_address() {
    let text = broken("\"name\": \"B\"", "\"name\": \"1B\"");
    expect_error(&text, "\"1B\"", 0, 0, "not an NC address");
}

#[test]
fn output_order_naming_an_unknown_joint() {
    let text = broken(
        "[\"X\", \"Z\", \"B\", \"C\"]",
        "[\"X\", \"Y\", \"B\", \"C\"]",
    );
    expect_error(
        &text,
        "\"Y\"",
        0,
        0,
        "\"output_order\" names \"Y\", which is not a joint",
    );
}

#[test]
fn output_order_leaving_out_a_joint() {
    let text = broken("[\"X\", \"Z\", \"B\", \"C\"]", "[\"X\", \"B\", \"C\"]");
    expect_error(&text, "\"output_order\"", 0, 0, "leaves out joint \"Z\"");
}

#[test]
fn output_order_naming_a_joint_twice() {
    let text = broken(
        "[\"X\", \"Z\", \"B\", \"C\"]",
        "[\"X\", \"Z\", \"B\", \"C\", \"X\"]",
    );
    expect_error(&text, "\"X\"]", 0, 0, "names \"X\" twice");
}

#[test]
fn limited_rotary_without_limits() {
    let text = broken(
        "\"B\": {\"min\": -90, \"max\": 90}",
        "\"B\": {\"rotary\": \"limited\", \"max\": 90}",
    );
    expect_error(
        &text,
        "\"rotary\": \"limited\"",
        0,
        0,
        "limited rotary axis \"B\" needs both \"min\" and \"max\"",
    );
}

#[test]
fn rotary_without_settings() {
    let text = broken(
        "    \"C\": {\"rotary\": \"continuous\"}\n",
        "    \"_C\": \"left out\"\n",
    );
    expect_error(
        &text,
        "\"C\"",
        0,
        0,
        "rotary axis \"C\" has no entry in \"axes\"",
    );
}

#[test]
fn continuous_rotary_with_limits() {
    let text = broken(
        "\"C\": {\"rotary\": \"continuous\"}",
        "\"C\": {\"rotary\": \"continuous\", \"max\": 720}",
    );
    expect_error(&text, "\"max\": 720", 0, 0, "has no travel limits");
}

#[test]
fn unknown_rotary_mode() {
    let text = broken("\"rotary\": \"continuous\"", "\"rotary\": \"endless\"");
    expect_error(&text, "\"endless\"", 0, 0, "unknown rotary mode");
}

#[test]
fn unknown_axis_setting() {
    let text = broken(
        "\"Z\": {\"min\": -100",
        "\"Z\": {\"mn\": -100, \"min\": -100",
    );
    expect_error(&text, "\"mn\"", 0, 0, "unknown key \"mn\"");
}

#[test]
fn axes_naming_an_unknown_joint() {
    let text = broken(
        "\"Z\": {\"min\": -100, \"max\": 100},",
        "\"Z\": {\"min\": -100, \"max\": 100},\n    \"Q\": {},",
    );
    expect_error(
        &text,
        "\"Q\"",
        0,
        0,
        "\"axes\" names \"Q\", which is not a joint",
    );
}

#[test]
fn min_above_max() {
    let text = broken(
        "\"Z\": {\"min\": -100, \"max\": 100}",
        "\"Z\": {\"min\": 100, \"max\": -100}",
    );
    expect_error(
        &text,
        "\"min\": 100",
        0,
        0,
        "min 100 is greater than max -100",
    );
}

#[test]
fn decimals_out_of_range() {
    let text = broken("\"decimals\": 4", "\"decimals\": 40");
    expect_error(
        &text,
        "40",
        0,
        0,
        "\"decimals\" as a whole number from 0 to 12",
    );
}

#[test]
fn wrong_value_type() {
    let text = broken("\"min\": -90", "\"min\": \"-90\"");
    expect_error(
        &text,
        "\"-90\"",
        0,
        0,
        "expected \"min\" (degrees) (a finite number)",
    );
}

#[test]
fn unknown_top_level_key() {
    let text = broken("\"description\"", "\"descripton\"");
    expect_error(
        &text,
        "\"descripton\"",
        0,
        0,
        "unknown key \"descripton\" in the machine description",
    );
}

#[test]
fn missing_chain() {
    let text = "{\n  \"name\": \"no chain\"\n}\n";
    expect_error(text, "{", 0, 0, "needs \"chain\"");
}

#[test]
fn empty_chain_and_chain_without_joints() {
    expect_error("{\"chain\": []}", "[", 0, 0, "the chain is empty");
    expect_error(
        "{\"chain\": [{\"translate\": [1, 2, 3]}]}",
        "[",
        0,
        0,
        "no joints",
    );
}

#[test]
fn too_many_joints() {
    let joints: Vec<String> = "XYZUVWA"
        .chars()
        .chain(['B'])
        .map(|c| format!("{{\"prismatic\": {{\"name\": \"{c}\", \"axis\": [1, 0, 0]}}}}"))
        .collect();
    let text = format!("{{\"chain\": [\n{}\n]}}", joints.join(",\n"));
    expect_error(&text, "{\"prismatic\": {\"name\": \"B\"", 0, 0, "at most 7");
}

#[test]
fn top_level_must_be_an_object() {
    expect_error("\n  [1, 2]", "[", 0, 0, "expected a machine description");
}

#[test]
fn load_reports_missing_files_as_io_errors() {
    let err = Machine::load(std::path::Path::new("/nonexistent/machine.json")).unwrap_err();
    assert!(matches!(err, Error::Io { .. }));
    assert!(err.to_string().starts_with("/nonexistent/machine.json: "));
}

#[test]
fn load_reads_a_file_and_names_it_in_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.json");
    std::fs::write(&path, broken("\"axis\": [0, 1, 0]", "\"axis\": [0, 0, 0]")).unwrap();
    let err = Machine::load(&path).unwrap_err().to_string();
    assert!(
        err.starts_with(&format!("{}:8:40: ", path.display())),
        "{err}"
    );
    let good = dir.path().join("good.json");
    std::fs::write(&good, GOOD).unwrap();
    assert_eq!(Machine::load(&good).unwrap().name, "test-xzbc");
}

#[test]
fn errors_show_the_offending_line() {
    let text = broken("\"axis\": [0, 1, 0]", "\"axis\": [0, 0, 0]");
    let err = Machine::from_json_str(&text, "m.json")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("\n  | ") && err.contains("\"axis\": [0, 0, 0]"),
        "{err}"
    );
}

#[test]
fn embedded_machines_are_listed_and_found() {
    let names = Machine::embedded_names();
    assert!(names.contains(&"zhao2022-xzbc") && names.contains(&"wang2023-xyzab"));
    for n in &names {
        assert!(Machine::embedded(n).is_some(), "{n}");
    }
    assert!(Machine::embedded("no-such-machine").is_none());
    assert_eq!(
        Machine::embedded("WANG2023-XYZAB").unwrap().name,
        "wang2023-xyzab"
    );
}

#[test]
fn duplicate_keys_are_refused_at_the_second() {
    // The last of duplicate keys used to win silently: ±30…110 became ±300.
    let text = broken(
        "\"B\": {\"min\": -90, \"max\": 90}",
        "\"B\": {\"min\": -30, \"max\": 110, \"min\": -300, \"max\": 300}",
    );
    expect_error(&text, "\"min\"", 3, 0, "duplicate key \"min\"");
    let text = broken("\"description\"", "\"name\": \"again\", \"description\"");
    expect_error(&text, "\"name\"", 1, 0, "duplicate key \"name\"");
    // Two "axes" objects.
    let text = broken("\"output_order\"", "\"axes\": {}, \"output_order\"");
    expect_error(&text, "\"axes\"", 1, 0, "duplicate key \"axes\"");
}

#[test]
fn misspelt_keys_are_refused_with_the_known_keys() {
    let text = broken(
        "\"X\": {\"min\": -100, \"max\": 100,",
        "\"X\": {\"limts\": [-100, 100],",
    );
    expect_error(&text, "\"limts\"", 0, 0, "unknown key \"limts\"");
    let err = Machine::from_json_str(&text, "m.json")
        .unwrap_err()
        .to_string();
    assert!(err.contains("\"min\", \"max\" or \"decimals\""), "{err}");
    let text = broken("\"axes\"", "\"axis\"");
    expect_error(&text, "\"axis\": {\n", 0, 0, "unknown key \"axis\"");
}

#[test]
fn joints_named_like_other_words_are_refused() {
    for word in [
        "M", "G", "S", "T", "N", "F", "I", "J", "K", "R", "P", "Q", "H", "D", "L", "O", "E", "C2",
        "XX",
    ] {
        let text = broken("\"name\": \"B\"", &format!("\"name\": \"{word}\""));
        expect_error(
            &text,
            &format!("\"{word}\""),
            0,
            0,
            &format!("joint name \"{word}\" is not an NC address"),
        );
    }
    let text = broken("\"name\": \"B\"", "\"name\": \"M\"");
    let err = Machine::from_json_str(&text, "m.json")
        .unwrap_err()
        .to_string();
    assert!(err.contains("\"M-90.0000\""), "{err}");
    // Every axis address is accepted, in either case.
    for word in ["U", "V", "W", "A", "b"] {
        let text = GOOD.replace("\"B\"", &format!("\"{word}\""));
        Machine::from_json_str(&text, "m.json").unwrap_or_else(|e| panic!("{word}: {e}"));
    }
}

#[test]
fn a_byte_order_mark_is_accepted_and_columns_stay_those_of_the_file() {
    let with_bom = format!("\u{feff}{GOOD}");
    let m = Machine::from_json_str(&with_bom, "m.json").unwrap();
    assert_eq!(m.name, "test-xzbc");
    let dir = std::env::temp_dir().join(format!("kinpost-bom-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bom.json");
    std::fs::write(&path, with_bom.as_bytes()).unwrap();
    assert_eq!(Machine::load(&path).unwrap().name, "test-xzbc");
    std::fs::remove_dir_all(&dir).unwrap();
    // An error on line 1 after the mark: the byte column of the file.
    let err = Machine::from_json_str("\u{feff}{\"chain\": 5}", "m.json").unwrap_err();
    assert!(err.to_string().starts_with("m.json:1:14: "), "{err}");
}

/// A chain of `n` elements: one joint and `n − 1` translations.
fn long_chain(n: usize) -> String {
    let mut s =
        String::from("{\"chain\": [{\"prismatic\": {\"name\": \"X\", \"axis\": [1, 0, 0]}}");
    for _ in 1..n {
        s.push_str(",\n{\"translate\": [0, 0, 1]}");
    }
    s.push_str("]}");
    s
}

#[test]
fn long_chains_are_capped_and_load_in_linear_time() {
    use kinpost::machine::file::MAX_CHAIN_ELEMENTS;
    let m = Machine::from_json_str(&long_chain(MAX_CHAIN_ELEMENTS), "m.json").unwrap();
    assert_eq!(m.chain.elements().len(), MAX_CHAIN_ELEMENTS);
    let q = m.to_internal(&[2.0]);
    let tip = m.chain.pose(&q, &kinpost::machine::NoErrors).tip;
    assert!(
        (tip - nalgebra::Vector3::new(2.0, 0.0, (MAX_CHAIN_ELEMENTS - 1) as f64)).norm() < 1e-9
    );
    let text = long_chain(MAX_CHAIN_ELEMENTS + 1);
    expect_error(
        &text,
        "{\"translate\"",
        MAX_CHAIN_ELEMENTS - 1,
        0,
        "at most 256",
    );
    // 100 000 elements used to take a minute; now they are refused at once.
    let text = long_chain(100_000);
    let start = std::time::Instant::now();
    let err = Machine::from_json_str(&text, "m.json")
        .unwrap_err()
        .to_string();
    assert!(err.contains("the chain has 100000 elements"), "{err}");
    assert!(start.elapsed().as_secs_f64() < 5.0, "{:?}", start.elapsed());
}
