//! The APT CL statement reader on arbitrary bytes: it must never panic, every
//! error must carry a location, and every motion it returns must be finite.
#![no_main]

use kinpost::cl::{ClReader, ClStatement, looks_like_cl};
use kinpost::error::Error;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = looks_like_cl(data);
    for record in ClReader::new(data, "fuzz.cls") {
        match record {
            Ok(r) => {
                assert!(r.line >= 1 && r.col >= 1, "record without a position");
                match r.statement {
                    ClStatement::Goto { tip, axis } => {
                        assert!(tip.iter().all(|v| v.is_finite()), "non-finite GOTO tip");
                        if let Some(a) = axis {
                            assert!(a.iter().all(|v| v.is_finite()), "non-finite GOTO axis");
                        }
                    }
                    ClStatement::TlAxis(a) => {
                        assert!(a.iter().all(|v| v.is_finite()), "non-finite TLAXIS");
                    }
                    ClStatement::Fedrat { value, .. } => {
                        assert!(value.is_finite(), "non-finite FEDRAT");
                    }
                    _ => {}
                }
            }
            Err(Error::Input { loc, .. }) => {
                assert_eq!(loc.file, "fuzz.cls");
                assert!(loc.line >= 1, "input error without a line: {loc}");
            }
            Err(e) => panic!("unexpected error kind from a slice: {e}"),
        }
    }
});
