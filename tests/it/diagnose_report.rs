//! The report's contract: the JSON of `formats.md` §3 with its exact field
//! names, a text form with units, an SVG, and located errors on bad input.

use crate::diagnose_support::*;
use kinpost::diagnose::{DiagOptions, Recording, diagnose, parse_effect_spec, simulate};

#[test]
fn json_has_exactly_the_formats_fields() {
    let (rec, r) = Machine::Wang
        .scenario(50, 21)
        .run(&effects(&["zero_offset:Z=0.003@block=20"]));
    let j = r.to_json();
    for k in FORMATS_FIELDS {
        assert!(j.get(k).is_some(), "missing {k}");
    }
    assert_eq!(j["samples"].as_u64(), Some(rec.len() as u64));
    let f = &j["findings"][0];
    assert_eq!(f["effect"], "zero_offset");
    assert_eq!(f["axis"], "Z");
    assert!(f["parameters"]["value_mm"].as_f64().is_some());
    assert!(f["uncertainty"]["value_mm"].as_f64().is_some());
    let w = &f["where"];
    assert_eq!(w["blocks"].as_array().unwrap().len(), 2);
    assert_eq!(w["t_s"].as_array().unwrap().len(), 2);
    assert!(w["condition"].as_str().unwrap().contains("from block"));
    assert!(f["rms_explained_mm"].as_f64().unwrap() > 0.0);
    assert!(f["runner_up"]["effect"].as_str().is_some());
    assert!(
        j["verdict"]
            .as_str()
            .unwrap()
            .starts_with("missing physics found")
    );
    let text = r.to_text();
    assert!(
        text.contains("µm") && text.contains("zero_offset Z"),
        "{text}"
    );
    let svg = r.to_svg().unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("time (s)"));
}

/// A thermal drift that starts part-way reports its onset time with a
/// standard deviation (`onset_sd_s`, an added field), and τ's uncertainty
/// includes the onset's; other findings have no `onset_sd_s`.
#[test]
fn part_way_drift_reports_the_onset_uncertainty() {
    let sc = Machine::Zhao.scenario(60, 5);
    let (_, r) = sc.run(&effects(&["thermal_drift:Z=0.004,tau=40@block=15"]));
    let j = r.to_json();
    let f = &j["findings"][0];
    assert_eq!(f["effect"], "thermal_drift", "{}", r.to_text());
    let sd = f["onset_sd_s"].as_f64().unwrap();
    assert!(sd > 0.0 && sd < 20.0, "{sd}");
    let tau = f["parameters"]["tau_s"].as_f64().unwrap();
    let tau_sd = f["uncertainty"]["tau_s"].as_f64().unwrap();
    assert!(tau_sd > 0.0 && tau_sd < tau, "{tau} ± {tau_sd}");
    let cond = f["where"]["condition"].as_str().unwrap();
    assert!(cond.contains(&format!("± {sd:.1} s)")), "{cond}");
    // A step effect from a block has no smooth onset parameter.
    let (_, r) = sc.run(&effects(&["zero_offset:Z=0.003@block=20"]));
    let j = r.to_json();
    assert_eq!(j["findings"][0]["effect"], "zero_offset");
    assert!(j["findings"][0].get("onset_sd_s").is_none());
}

#[test]
fn clean_recording_says_consistent_with_noise() {
    let sc = Machine::Zhao.scenario(40, 8);
    let (rec, r) = sc.run(&[]);
    assert!(r.findings.is_empty());
    assert!(
        r.verdict.starts_with("consistent with measurement noise"),
        "{}",
        r.verdict
    );
    assert_eq!(r.to_json()["findings"], serde_json::json!([]));
    assert!(r.to_svg().is_ok());
    // Without the error model the fixture errors are the mismatch: found,
    // but not as noise.
    let r = diagnose(&sc.chain, None, &rec, &DiagOptions::default()).unwrap();
    assert!(!r.verdict.starts_with("consistent"), "{}", r.verdict);
}

#[test]
fn bad_recordings_are_located_errors() {
    let chain = zhao();
    let axes: Vec<String> = chain.joints().iter().map(|j| j.name.clone()).collect();
    let text =
        "t,block,C,X,Z,B,meas_x,meas_y,meas_z\n0,1,0,0,0,0,0,0,-20\n0.1,1,0,0,0,inf,0,0,-20\n";
    let e = Recording::parse(text, "r.csv", &axes)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("r.csv:3:13:"), "{e}");
    let short = Recording::parse(
        "t,C,X,Z,B,meas_x,meas_y,meas_z\n0,0,0,0,0,0,0,-20\n",
        "r.csv",
        &axes,
    )
    .unwrap();
    let e = diagnose(&chain, None, &short, &DiagOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("at least 20"), "{e}");
    // Simulation and diagnosis are deterministic.
    let m = Machine::Zhao;
    let p = m.program(10, 1);
    let a = simulate(&chain, None, &p, &[], &sim_options(4)).unwrap();
    let b = simulate(&chain, None, &p, &[], &sim_options(4)).unwrap();
    assert_eq!(a, b);
    let spec = parse_effect_spec("backlash:Q=0.003").unwrap();
    assert!(simulate(&chain, None, &p, &[spec], &sim_options(4)).is_err());
}
