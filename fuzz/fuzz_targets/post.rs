//! The whole post path on arbitrary bytes: input-kind detection, the G-code
//! or APT CL converter, IK, limits, the emitter. It must never panic; an
//! error must be an input error with a location; a program that converts
//! must not contain a non-finite axis word.
#![no_main]

use kinpost::cl::looks_like_cl;
use kinpost::error::Error;
use kinpost::machine::{IkSolver, Machine};
use kinpost::post::{PostOptions, post_cl, post_gcode};
use kinpost::program::PoseStart;
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

fn machines() -> &'static [Machine; 2] {
    static M: OnceLock<[Machine; 2]> = OnceLock::new();
    M.get_or_init(|| {
        [
            Machine::embedded_default(),
            Machine::embedded("wang2023-xyzab").expect("embedded machine"),
        ]
    })
}

fuzz_target!(|data: &[u8]| {
    // The first byte chooses the machine and the options; the rest is the program.
    let Some((&sel, program)) = data.split_first() else {
        return;
    };
    let machine = &machines()[usize::from(sel & 1)];
    let opts = PostOptions {
        decimals: (sel & 2 != 0).then_some(u32::from(sel >> 4) % 13),
        pose_start: if sel & 4 != 0 {
            PoseStart::Off
        } else {
            PoseStart::On
        },
        axis_tolerance_rad: if sel & 8 != 0 { f64::INFINITY } else { 1e-4 },
        modal_axes: sel & 16 != 0,
        file_name: "fuzz.nc".into(),
        ..PostOptions::default()
    };
    let mut solver = IkSolver::new(machine);
    let mut out = Vec::new();
    let result = if looks_like_cl(&program[..program.len().min(4096)]) {
        post_cl(machine, &mut solver, program, &mut out, &opts, |_| {})
    } else {
        post_gcode(machine, &mut solver, program, &mut out, &opts, |_| {})
    };
    match result {
        Ok(_) => {
            let text = String::from_utf8_lossy(&out).to_ascii_lowercase();
            let input = String::from_utf8_lossy(program).to_ascii_lowercase();
            for bad in ["nan", "inf"] {
                assert!(
                    !text.contains(bad) || input.contains(bad),
                    "output holds `{bad}` that the input did not"
                );
            }
        }
        Err(Error::Input { loc, .. }) => {
            assert_eq!(loc.file, "fuzz.nc");
        }
        Err(e) => panic!("unexpected error kind: {e}"),
    }
});
