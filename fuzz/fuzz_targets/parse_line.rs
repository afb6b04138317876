//! The G-code line parser on arbitrary bytes: it must never panic, its items
//! must tile the line, and writing the line back must give the input.
#![no_main]

use kinpost::gcode::{LineReader, parse_line};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // One physical line as the reader would hand it over (up to the first LF).
    let end = data
        .iter()
        .position(|&b| b == b'\n')
        .map_or(data.len(), |i| i + 1);
    let line = parse_line(&data[..end], 1);
    assert!(line.is_tiled(), "items do not tile the line");
    let mut out = Vec::new();
    line.write_to(&mut out)
        .expect("writing to a Vec cannot fail");
    assert_eq!(out, &data[..end], "echo differs from the input line");
    for w in line.words() {
        assert!(w.value.is_finite(), "non-finite word value {:?}", w.value);
    }

    // The whole input as a program: the echo is byte-identical.
    let mut echoed = Vec::new();
    for l in LineReader::new(data) {
        l.expect("reading from a slice cannot fail")
            .write_to(&mut echoed)
            .expect("writing to a Vec cannot fail");
    }
    assert_eq!(echoed, data, "program echo differs from the input");
});
