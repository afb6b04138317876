//! The readers of the other inputs on arbitrary bytes: machine files, error
//! tables and models, recordings and --inject specs. They must never panic;
//! every failure is an input error (exit 1) naming the file.
#![no_main]

use kinpost::diagnose::parse_effect_spec;
use kinpost::diagnose::recording::Recording;
use kinpost::error::Error;
use kinpost::geometric::model::ErrorModel;
use kinpost::geometric::table::parse_tables;
use kinpost::machine::Machine;
use kinpost::text::into_utf8;
use libfuzzer_sys::fuzz_target;

fn input_error<T>(r: Result<T, Error>) {
    if let Err(e) = r {
        assert!(matches!(e, Error::Input { .. }), "not an input error: {e}");
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&sel, bytes)) = data.split_first() else {
        return;
    };
    let text = match into_utf8(bytes.to_vec(), "f", 1) {
        Ok(t) => t,
        Err(e) => {
            assert!(matches!(e, Error::Input { .. }));
            return;
        }
    };
    match sel % 5 {
        0 => input_error(Machine::from_json_str(&text, "m.json").map(|m| {
            // A machine that loads must also solve without panicking.
            let ik = kinpost::machine::IkSolver::new(&m);
            let pose = kinpost::machine::Pose::new(
                nalgebra::Vector3::new(1.0, 2.0, 3.0),
                nalgebra::Vector3::new(0.0, 0.6, 0.8),
            );
            let _ = ik.solve(&pose, None);
        })),
        1 => input_error(parse_tables(&text, "t.csv")),
        2 => input_error(ErrorModel::from_str_auto(&text, "e.json")),
        3 => {
            let axes: Vec<String> = ["C", "X", "Z", "B"].iter().map(|s| s.to_string()).collect();
            input_error(Recording::parse(&text, "r.csv", &axes));
        }
        _ => {
            let _ = parse_effect_spec(&text);
        }
    }
});
