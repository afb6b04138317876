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
            "t,X,Z,B,C,meas_x,meas_y,meas_z\n0,1,1,1,1,1,1,1\n0.5,1,1,1,1,1,1,5\n1,1,1,1,1,1,1,2;5\n",
            "r.csv:4:15: meas_z (mm): `2;5` is not a number",
        ),
    ] {
        let e = Recording::parse(text, "r.csv", &axes())
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{e}");
    }
}

/// Three dialects the thirteenth hunt found refused with a message that
/// did not name the cause (session 30): a comma inside a column name of a
/// `;`-separated file (the whole header read as one column: "no `t`
/// column"), a header written as a comment (`# t,block,…`, as NumPy's
/// savetxt writes it: "no `t` column" at the first sample), and a units
/// row under the header ("`s` is not a number"). The comment header and a
/// units row now read to the same samples as the plain form; the comma
/// in a name is named as the column it is.
#[test]
fn comment_headers_units_rows_and_commas_in_names() {
    let plain = Recording::parse(PLAIN, "plain.csv", &axes()).unwrap();
    let mut lines = PLAIN.lines();
    let header = lines.next().unwrap();
    let body: String = lines.map(|l| format!("{l}\n")).collect();
    let commented = format!("# recorded 2026-11-28\n# {header}\n{body}");
    same(
        &Recording::parse(&commented, "c.csv", &axes()).unwrap(),
        &plain,
        "header as a comment",
    );
    // A units row: t in ms, the tip in µm, B in rad; the rest as named.
    let mut units = format!("{header}\nms,,mm,mm,rad,deg,um,um,um,°C\n");
    for s in &plain.samples {
        units.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{}\n",
            s.t * 1e3,
            s.block.unwrap(),
            s.q[0],
            s.q[1],
            s.q[2].to_radians(),
            s.q[3],
            s.meas[0] * 1e3,
            s.meas[1] * 1e3,
            s.meas[2] * 1e3,
            s.temps[0]
        ));
    }
    same(
        &Recording::parse(&units, "u.csv", &axes()).unwrap(),
        &plain,
        "units row",
    );
    // A units row with a unit of the wrong kind is refused at its column.
    let bad = format!("{header}\ns,,mm,mm,deg,deg,deg,mm,mm,C\n{body}");
    let e = Recording::parse(&bad, "b.csv", &axes())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.csv:2:18:") && e.contains("units row") && e.contains("meas_x"),
        "{e}"
    );
    // Numbers only, no header at all: said so.
    let e = Recording::parse(&body, "n.csv", &axes())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("n.csv:1:1:") && e.contains("numbers only"),
        "{e}"
    );
    // `;`-separated with a comma in a column name: the column is named.
    let semi = PLAIN
        .replace(',', ";")
        .replace('.', ",")
        .replacen("meas_x", "meas,x", 1);
    let e = Recording::parse(&semi, "s.csv", &axes())
        .unwrap_err()
        .to_string();
    assert!(e.contains("no `meas_x` column"), "{e}");
    let fixed = semi.replacen("meas,x", "meas_x", 1);
    same(
        &Recording::parse(&fixed, "s.csv", &axes()).unwrap(),
        &plain,
        "semicolons",
    );
}
