//! Unit tests of the lowering of CL statements.

use super::*;
use crate::cl::ClReader;
use crate::cl::FeedUnit;
use crate::cl::vec3::sub;

pub(crate) fn run(text: &str) -> Result<Vec<ClStatement>, Error> {
    lower(ClReader::new(text.as_bytes(), "t.apt"), "t.apt", 1e-3, None)
        .map(|r| r.map(|r| r.statement))
        .collect()
}

/// The statements with arcs and holes replaced by their moves.
pub(crate) fn flat(s: &[ClStatement]) -> Vec<ClStatement> {
    s.iter()
        .flat_map(|s| match s {
            ClStatement::Arc(a) => a.moves.clone(),
            ClStatement::Hole(h) => h.moves.clone().unwrap_or_default(),
            other => vec![other.clone()],
        })
        .collect()
}

pub(crate) fn gotos(s: &[ClStatement]) -> Vec<[f64; 3]> {
    flat(s)
        .iter()
        .filter_map(|s| match s {
            ClStatement::Goto { tip, .. } => Some(*tip),
            _ => None,
        })
        .collect()
}

pub(crate) fn blocks(s: &[ClStatement]) -> Vec<String> {
    flat(s)
        .iter()
        .filter_map(|s| match s {
            ClStatement::Block(b) | ClStatement::CutterCompensation { block: b, .. } => {
                Some(b.clone())
            }
            _ => None,
        })
        .collect()
}

pub(crate) fn near(a: [f64; 3], b: [f64; 3]) -> bool {
    norm(sub(a, b)) < 1e-9
}

#[test]
fn spindle_forms() {
    let s = run("SPINDL/12000,RPM,CLW\nSPINDL/RPM,800,CCLW\nSPINDL/SMM,200,CLW\nSPINDL/SFM,100,CCLW\nSPINDL/OFF\n").unwrap();
    assert!(matches!(
        s[0],
        ClStatement::Spindle {
            rpm: Some(12000.0),
            dir: Some(crate::cl::SpindleDir::Clockwise),
            off: false
        }
    ));
    assert!(matches!(
        s[1],
        ClStatement::Spindle {
            rpm: Some(800.0),
            dir: Some(crate::cl::SpindleDir::CounterClockwise),
            off: false
        }
    ));
    assert_eq!(blocks(&s), ["G96 S200 M3", "G96 S30.48 M4"]);
    assert!(matches!(s[4], ClStatement::Spindle { off: true, .. }));
}

#[test]
fn tools_and_cutcom() {
    let s = run("LOAD/TOOL,3,ADJUST,13\nSELECT/TOOL,4\nCUTCOM/LEFT\nCUTCOM/RIGHT\nCUTCOM/OFF\n")
        .unwrap();
    assert_eq!(
        blocks(&s),
        ["T3 M6", "G43 H13", "T4", "G41 D3", "G42 D3", "G40"]
    );
}

/// CSYS: the set-up frame's axes are the matrix columns, its origin the
/// last column; points become `Rᵀ (p − t)`.
#[test]
fn csys_translation_and_rotation() {
    let s = run("UNITS/MM\nCSYS/1,0,0,10,0,1,0,20,0,0,1,30\nGOTO/11,22,33\n").unwrap();
    assert!(near(gotos(&s)[0], [1.0, 2.0, 3.0]));
    // Set-up X along CL -Z, Z along CL +X (a quarter turn about Y).
    let s = run("UNITS/MM\nCSYS/0,0,1,0,0,1,0,0,-1,0,0,0\nGOTO/250,5,-12,1,0,0\n").unwrap();
    match &s[2] {
        ClStatement::Goto { tip, axis } => {
            assert!(near(*tip, [12.0, 5.0, 250.0]), "{tip:?}");
            assert!(near(axis.unwrap(), [0.0, 0.0, 1.0]));
        }
        other => panic!("{other:?}"),
    }
    let e = run("CSYS/2,0,0,0,0,1,0,0,0,0,1,0\n").unwrap_err();
    assert!(e.to_string().contains("t.apt:1:1"));
}

/// A `CSYS` turns the tool axis to the new frame's Z: the three-value
/// `GOTO`s of an operation after one with six values along another
/// frame's Z are along their own frame's (SolidWorks CAM; before, the
/// earlier operation's axis, 0.29° off, was kept).
#[test]
fn csys_turns_the_tool_axis_to_its_z() {
    let tilted = "CSYS/0,.999987,.005061,0,-1,0,0,0,0,-0.005061,.999987,0";
    let s = run(&format!(
        "UNITS/MM\n{tilted}\nGOTO/1,2,3,.005061,0,.999987\nCSYS/1,0,0,0,0,1,0,0,0,0,1,0\nGOTO/4,5,6\n"
    ))
    .unwrap();
    let axes: Vec<[f64; 3]> = s
        .iter()
        .filter_map(|s| match s {
            ClStatement::Goto { axis, .. } => *axis,
            _ => None,
        })
        .collect();
    assert_eq!(axes.len(), 2);
    // (The six-value axis is printed to six decimals.)
    assert!(norm(sub(axes[0], [0.0, 0.0, 1.0])) < 1e-6, "{:?}", axes[0]);
    assert_eq!(axes[1], [0.0, 0.0, 1.0]);
    // Into a tilted frame with three values: along that frame's Z.
    let s = run(&format!("UNITS/MM\n{tilted}\nGOTO/1,2,3\n")).unwrap();
    match s.last() {
        Some(ClStatement::Goto { axis, .. }) => {
            assert!(norm(sub(axis.unwrap(), [0.0, 0.0, 1.0])) < 1e-6, "{axis:?}")
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn per_revolution_feeds() {
    let s = run("UNITS/MM\nFEDRAT/0.1,MMPR\nFEDRAT/IPR,0.01\nFEDRAT/500,MMPM\n").unwrap();
    assert_eq!(blocks(&s), ["G95", "G94"]);
    let f: Vec<f64> = s
        .iter()
        .filter_map(|s| match s {
            ClStatement::Fedrat {
                value,
                unit: FeedUnit::Mmpm,
            } => Some(*value),
            _ => None,
        })
        .collect();
    assert_eq!(f.len(), 3);
    assert!((f[1] - 0.254).abs() < 1e-12);
}

#[test]
fn never_silent() {
    let e = run("UNITS/MM\nGOTO/0,0,0\nGOFWD/S1,TANTO,S2\n").unwrap_err();
    assert!(e.to_string().contains("t.apt:3:1"), "{e}");
    let e = run("UNITS/MM\nFEDRAT/MMPM,1e300\n").unwrap_err();
    assert!(e.to_string().contains("t.apt:2:1"), "{e}");
    // No UNITS: a warning, millimetres; comments are counted.
    let s = run("PARTNO/X\nGOTO/0,0,0\n").unwrap();
    let warnings: Vec<_> = s
        .iter()
        .filter(|s| matches!(s, ClStatement::Warning(_)))
        .collect();
    assert_eq!(warnings.len(), 2, "{s:?}");
}
