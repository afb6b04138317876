//! Recordings as controllers and trace tools export them (`formats.md` §2,
//! §2b, §2c): a semicolon or tab as the separator with a decimal comma,
//! quoted fields, units in the column names. Each dialect must read to the
//! same samples as the plain form (before: "the header has no `t` column"
//! on every one of them); a unit of the wrong kind is refused at its column.

use kinpost::diagnose::Recording;
use kinpost::diagnose::feedback::FeedbackRecording;

fn axes() -> Vec<String> {
    ["X", "Z", "B", "C"].iter().map(|s| s.to_string()).collect()
}

/// The plain form of `formats.md` §2: three samples.
const PLAIN: &str = "t,block,X,Z,B,C,meas_x,meas_y,meas_z,temp_spindle\n\
                     0.000,1,10.0,5.0,0.0,0.0,10.0011,0.0002,-14.9993,21.5\n\
                     0.125,1,10.5,4.75,1.5,-30.25,10.4987,-0.0013,-15.2401,21.6\n\
                     0.250,2,11.0,4.5,3.0,-60.5,11.0006,0.0021,-15.4822,21.8\n";

fn same(a: &Recording, b: &Recording, what: &str) {
    assert_eq!(a.samples.len(), b.samples.len(), "{what}");
    assert_eq!(a.temp_names, b.temp_names, "{what}");
    for (s, u) in a.samples.iter().zip(&b.samples) {
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * (1.0 + x.abs());
        assert!(close(s.t, u.t), "{what}: t {} vs {}", s.t, u.t);
        assert_eq!(s.block, u.block, "{what}");
        for (x, y) in
            s.q.iter()
                .chain(&s.meas)
                .chain(&s.temps)
                .zip(u.q.iter().chain(&u.meas).chain(&u.temps))
        {
            assert!(close(*x, *y), "{what}: {x} vs {y}");
        }
    }
}

#[test]
fn export_dialects_read_as_the_plain_form() {
    let plain = Recording::parse(PLAIN, "plain.csv", &axes()).unwrap();
    // German-locale export: semicolons, decimal commas, quoted header.
    let german =
        PLAIN
            .replace(',', ";")
            .replace('.', ",")
            .replacen("t;block", "\"t\";\"block\"", 1);
    // Tab-separated with quoted values.
    let tabs = PLAIN.replace(',', "\t").replace("\t1\t", "\t\"1\"\t");
    // Units in the names: t in ms, B and C in rad, the tip in µm.
    let mut units = String::from(
        "t [ms],block,X [mm],Z,B[rad],C [rad],meas_x [um],meas_y [um],meas_z [um],temp_spindle [°C]\n",
    );
    for line in PLAIN.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|f| f.parse().unwrap()).collect();
        let w = [
            v[0] * 1e3,
            v[1],
            v[2],
            v[3],
            v[4].to_radians(),
            v[5].to_radians(),
            v[6] * 1e3,
            v[7] * 1e3,
            v[8] * 1e3,
            v[9],
        ];
        let row: Vec<String> = w.iter().map(|x| format!("{x:?}")).collect();
        units.push_str(&row.join(","));
        units.push('\n');
    }
    // Units in parentheses and a `Time` column (the sixth hunt: "the
    // header has no `t` column", with the column there).
    let parens = units
        .replacen("t [ms]", "Time (ms)", 1)
        .replacen("C [rad]", "C (rad)", 1)
        .replacen("meas_x [um]", "meas_x (um)", 1);
    for (what, text) in [
        ("german", german),
        ("tabs", tabs),
        ("units", units),
        ("parens", parens),
    ] {
        let r = Recording::parse(&text, "r.csv", &axes()).unwrap_or_else(|e| panic!("{what}: {e}"));
        same(&plain, &r, what);
    }
}

#[test]
fn joint_feedback_dialects_read_as_the_plain_form() {
    let axes: Vec<String> = ["X", "Z", "B"].iter().map(|s| s.to_string()).collect();
    let rotary = [false, false, true];
    let plain = "t,X,fb_X,B,fb_B\n0.000,1.0,1.0002,10.0,10.001\n0.001,1.1,1.1003,10.5,10.4995\n";
    let german = "t [ms];X;fb_X [um];B;fb_B\n0;1,0;1000,2;10,0;10,001\n1;1,1;1100,3;10,5;10,4995\n";
    let read = |text: &str| {
        FeedbackRecording::read(text.as_bytes(), "fb.csv", &axes, &rotary, None)
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let (a, b) = (read(plain), read(german));
    assert_eq!(a.axes, b.axes);
    for (x, y) in
        a.t.iter()
            .chain(a.cmd.iter().flatten())
            .chain(a.fb.iter().flatten())
            .zip(
                b.t.iter()
                    .chain(b.cmd.iter().flatten())
                    .chain(b.fb.iter().flatten()),
            )
    {
        assert!((x - y).abs() <= 1e-12 * (1.0 + x.abs()), "{x} vs {y}");
    }
}

#[test]
fn wrong_units_and_misread_numbers_are_refused_at_their_column() {
    for (text, want) in [
        (
            "t,block,X [deg],Z,B,C,meas_x,meas_y,meas_z\n",
            "r.csv:1:9: column `X [deg]`: `deg` is not a unit of length",
        ),
        (
            "t [fortnight],X,Z,B,C,meas_x,meas_y,meas_z\n0,1,1,1,1,1,1,1\n",
            "r.csv:1:1: column `t [fortnight]`: `fortnight` is not a unit of time",
        ),
        (
            "t,X,Z,B,C,meas_x,meas_y,meas_z\n0,1,1,1,1,1,1,1\n0.5,1,1,1,1,1,1,1,5\n1,1,1,1,1,1,1,2;5\n",
            "r.csv:4:15: meas_z (mm): `2;5` is not a number",
        ),
    ] {
        let e = Recording::parse(text, "r.csv", &axes())
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{e}");
    }
}
