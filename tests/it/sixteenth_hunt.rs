//! Sixteenth hunt (session 32, `docs/robustness.md`): poses in a LinuxCNC
//! subroutine's body. Each test failed on the session's first build.

use crate::util::run_on;

/// A subroutine (`o100 sub` … `o100 endsub`) runs under the modes of each
/// call: its poses were converted under the modes where the body stands
/// in the file (here G21, called under G20: the machine would go 25.4
/// times as far), exit 0. Now such a pose is refused, naming the `sub`;
/// a subroutine without poses, and poses after its end, still convert.
#[test]
fn a_pose_in_a_subroutine_body_is_refused() {
    let body = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nG49\n";
    for command in ["post", "compensate"] {
        let mut args = vec![command, "--machine", "zhao2022-xzbc"];
        if command == "compensate" {
            args.extend(["--errors", "fixtures/errors/zhao2022-xzbc.csv"]);
        }
        for (open, close) in [
            ("o100 sub", "o100 endsub"),
            ("O<tilt> SUB", "O<tilt> ENDSUB"),
        ] {
            let program = format!("G21 G90\n{open}\n{body}{close}\nG20\no100 call\nM30\n");
            let (code, out, err) = run_on(&args, "sub.ngc", &program);
            assert_eq!(code, 1, "{command} {open}: {out}{err}");
            assert!(
                err.contains("sub.ngc:4:4:") && err.contains("`sub` at line 2"),
                "{command} {open}: {err}"
            );
            assert!(out.is_empty(), "{command}: {out}");
        }
        let program =
            format!("G21 G90\no100 sub\nG1 X1 Y2 Z3\no100 endsub\n{body}o100 call\nM30\n");
        let (code, out, err) = run_on(&args, "sub.ngc", &program);
        assert_eq!(code, 0, "{command}: {err}");
        assert!(
            out.contains("G1 X9.99") || out.contains("G1 X10.0"),
            "{command}: {out}"
        );
        assert!(
            out.contains("o100 sub\nG1 X1 Y2 Z3\no100 endsub\n"),
            "{command}: {out}"
        );
    }
}
