//! APT CL through the parallel driver (`post::pipeline::drive`): the output
//! of `post` and `compensate` does not depend on the number of threads nor
//! on where the chunks of 512 statements (`CHUNK_UNITS`) begin, on a
//! program of several chunks with arcs, holes (as canned cycles under
//! `post`, as moves under `compensate`) and `G80` blocks across the chunk
//! boundaries; and the motion code is written again after each `G80`
//! (under `compensate` the first pass of a chunk runs before the chunk
//! before it is written: the `G80` must reset the motion code in order).

use std::process::Command;

const TRT: &str = "fixtures/machines/xyzac-trt.json";

/// Times the motif of [`program`] is repeated.
const MOTIFS: usize = 130;

/// A program of about 1,700 statements: a motif of an arc, a drilled
/// hole, a cycle switched on and off right after a feed move, and feed
/// moves, repeated (shifted by a few micrometres each time), after `pad`
/// comments that move the chunk boundaries.
fn program(pad: usize) -> String {
    let mut s = String::from("UNITS/MM\nFEDRAT/MMPM,300\n");
    for _ in 0..pad {
        s.push_str("$$ pad\n");
    }
    for k in 0..MOTIFS {
        let d = k as f64 * 0.01;
        s.push_str(&format!(
            "GOTO/10,{d:.3},5\nCIRCLE/0,{d:.3},5,0,0,1\nGOTO/0,{y:.3},5\n\
             CYCLE/DRILL,FEDTO,4,RAPTO,2,RTRCTO,10\nGOTO/0,10,0\nCYCLE/OFF\n\
             GOTO/{d:.3},10,20\nGOTO/3,{d:.3},8\n\
             CYCLE/DEEP,FEDTO,3,STEP,1,RAPTO,2,RTRCTO,10\nCYCLE/OFF\n\
             GOTO/4,{d:.3},8\nFEDRAT/MMPM,{f}\nGOTO/5,{d:.3},8\n",
            y = 10.0 + d,
            f = 300 + (k % 3) * 100,
        ));
    }
    s.push_str("FINI\n");
    s
}

/// Runs kinpost with `args` on `program` (a file in a temporary
/// directory), with `RAYON_NUM_THREADS` set to `threads` when given;
/// returns the output program and the `--report` JSON (compensate), both
/// without the comment lines of the padding.
fn run(args: &[&str], program: &str, threads: Option<&str>, tag: &str) -> (String, String) {
    let dir = std::env::temp_dir().join(format!(
        "kinpost-cl-driver-{}-{tag}-{}",
        std::process::id(),
        threads.unwrap_or("all")
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let input = dir.join("p.cls");
    let output = dir.join("p.nc");
    let report = dir.join("r.json");
    std::fs::write(&input, program).unwrap();
    let mut cmd = Command::new(crate::util::BIN);
    cmd.current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .arg(&input)
        .arg("-o")
        .arg(&output);
    if args[0] == "compensate" {
        cmd.arg("--report").arg(&report);
    }
    match threads {
        Some(n) => cmd.env("RAYON_NUM_THREADS", n),
        None => cmd.env_remove("RAYON_NUM_THREADS"),
    };
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let nc = std::fs::read_to_string(&output).unwrap();
    let json = std::fs::read_to_string(&report).unwrap_or_default();
    std::fs::remove_dir_all(&dir).unwrap();
    // The padding and the input's name (in the header) aside.
    let nc = nc
        .lines()
        .filter(|l| *l != "(pad)" && !l.starts_with("(kinpost: APT CL"))
        .map(|l| format!("{l}\n"))
        .collect();
    (nc, json)
}

/// Every `G80` is followed by a block that states its motion code.
fn motion_after_g80(nc: &str) -> usize {
    let lines: Vec<&str> = nc.lines().collect();
    let mut n = 0;
    for (i, l) in lines.iter().enumerate() {
        if *l == "G80" {
            let next = lines.get(i + 1).copied().unwrap_or("");
            assert!(
                next.starts_with("G1 ") || next.starts_with("G0 "),
                "line {}: the block after G80 does not state its motion: {next:?}",
                i + 2
            );
            n += 1;
        }
    }
    n
}

#[test]
fn compensate_is_independent_of_threads_and_chunks() {
    let args = [
        "compensate",
        "-q",
        "-m",
        "wang2023-xyzab",
        "--errors",
        "fixtures/errors/wang2023-xyzab.csv",
    ];
    let reference = program(0);
    assert!(reference.lines().count() > 3 * 512);
    let (nc, json) = run(&args, &reference, None, "c0");
    assert_eq!(motion_after_g80(&nc), 2 * MOTIFS);
    // Holes are moves under compensate: no canned cycle, no G2/G3.
    assert!(!nc.contains("G81") && !nc.contains(" G2 ") && !nc.contains("G3 "));
    let one = run(&args, &reference, Some("1"), "c0");
    assert!(one.0 == nc, "compensate: 1 thread differs from all");
    assert!(
        one.1 == json,
        "compensate --report: 1 thread differs from all"
    );
    for pad in [1, 5, 11] {
        let (p, _) = run(&args, &program(pad), None, &format!("c{pad}"));
        assert!(p == nc, "compensate: padding {pad} moves the output");
    }
}

#[test]
fn post_is_independent_of_threads_and_chunks() {
    let args = ["post", "-q", "-m", TRT];
    let reference = program(0);
    let (nc, _) = run(&args, &reference, None, "p0");
    assert_eq!(motion_after_g80(&nc), 2 * MOTIFS);
    // Arcs as G2/G3 and holes as canned cycles, planned in the first pass.
    assert_eq!(nc.matches("G3 ").count(), MOTIFS);
    assert_eq!(nc.matches(" G81 ").count(), MOTIFS);
    assert_eq!(nc.matches(" G83 ").count(), 0);
    let (one, _) = run(&args, &reference, Some("1"), "p0");
    assert!(one == nc, "post: 1 thread differs from all");
    for pad in [1, 5, 11] {
        let (p, _) = run(&args, &program(pad), None, &format!("p{pad}"));
        assert!(p == nc, "post: padding {pad} moves the output");
    }
}
