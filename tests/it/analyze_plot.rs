//! `analyze --svg` keeps a fixed amount of memory and draws a file of a
//! fixed size, whatever the program's length (docs/robustness.md,
//! "`analyze --svg` thins its series as they come"): each series is thinned
//! to at most 1,024 buckets of consecutive blocks, and each bucket draws its
//! lowest and highest point (`kinpost::report::Envelope`, whose unit tests
//! check that every run's extremes are drawn). Before, every block's value
//! was kept and drawn: 568 MB and a 63 MB SVG for 2,000,000 blocks.

use kinpost::demo::{OffAxisLens, write_lens_spiral_program};

use crate::cl_support::kinpost;

/// The number of points of each `<polyline>` of an SVG document.
fn polyline_points(svg: &str) -> Vec<usize> {
    svg.split("<polyline")
        .skip(1)
        .map(|p| {
            let points = p.split("points=\"").nth(1).expect("points attribute");
            let points = &points[..points.find('"').expect("closing quote")];
            points.split_whitespace().count()
        })
        .collect()
}

#[test]
fn a_long_program_plots_a_bounded_number_of_points_per_series() {
    let dir = tempfile::tempdir().unwrap();
    let mut sizes = Vec::new();
    for poses in [1_000, 20_000] {
        let program = dir.path().join(format!("spiral-{poses}.nc"));
        let mut text = Vec::new();
        write_lens_spiral_program(&OffAxisLens::default(), poses, &mut text).unwrap();
        std::fs::write(&program, text).unwrap();
        let svg = dir.path().join(format!("spiral-{poses}.svg"));
        let out = kinpost(&[
            "analyze",
            "-m",
            "zhao2022-xzbc",
            "-e",
            "fixtures/errors/zhao2022-xzbc.csv",
            "--nonlinear",
            program.to_str().unwrap(),
            "--svg",
            svg.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(text.contains(&format!("{poses} poses")), "{text}");
        let svg = std::fs::read_to_string(&svg).unwrap();
        // The four data series (E, ε, exact, estimate) are the polylines
        // with more than a legend's two points.
        let series: Vec<usize> = polyline_points(&svg)
            .into_iter()
            .filter(|&n| n > 2)
            .collect();
        assert_eq!(series.len(), 4, "{poses} poses: {series:?}");
        if poses == 1_000 {
            // Up to 1,024 points a series, every point is drawn: one a pose
            // and one a measured block (every block after the first).
            assert_eq!(series, [poses, poses, poses - 1, poses - 1]);
        } else {
            assert!(series.iter().all(|&n| n > 512 && n <= 2_048), "{series:?}");
        }
        sizes.push(svg.len());
    }
    // Twenty times the blocks, a file of about the same size (it was
    // twenty times larger).
    assert!(sizes[1] < 3 * sizes[0], "{sizes:?}");
}
