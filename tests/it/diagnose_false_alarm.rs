//! Stay quiet: clean simulated recordings (the fixture geometric errors are
//! in the model, only measurement noise is missing from it) must give no
//! finding. The false-alarm rate over 40 seeds on each seed machine must be
//! at most 5 %.

use crate::diagnose_support::*;

const SEEDS: u64 = 40;

fn false_alarms(m: Machine) -> (usize, Vec<String>) {
    let blocks = match m {
        Machine::Zhao => 80,
        Machine::Wang => 70,
    };
    let seeds: Vec<u64> = (1000..1000 + SEEDS).collect();
    let results = par_map(&seeds, |&seed| {
        let (_, r) = m.scenario(blocks, seed).run(&[]);
        assert!(r.findings.is_empty() || r.verdict.starts_with("missing physics found"));
        if r.findings.is_empty() {
            assert!(
                r.verdict.starts_with("consistent with measurement noise"),
                "{}",
                r.verdict
            );
        }
        let names: Vec<String> = r
            .findings
            .iter()
            .map(|f| format!("{} {}", f.effect, f.axis.clone().unwrap_or_default()))
            .collect();
        let best = r
            .candidates
            .first()
            .map_or(f64::NEG_INFINITY, |c| c.delta_bic);
        (seed, names, best)
    });
    let mut alarms = Vec::new();
    for (seed, names, _) in &results {
        if !names.is_empty() {
            alarms.push(format!("seed {seed}: {}", names.join(", ")));
        }
    }
    let worst = results
        .iter()
        .map(|r| r.2)
        .fold(f64::NEG_INFINITY, f64::max);
    println!("{m:?}: largest first-round candidate ΔBIC on clean data {worst:.1} (margin 10)");
    (alarms.len(), alarms)
}

#[test]
fn false_alarm_rate_is_at_most_five_percent_on_both_machines() {
    let mut total = 0;
    for m in [Machine::Zhao, Machine::Wang] {
        let (n, list) = false_alarms(m);
        println!(
            "{m:?}: {n} false alarms in {SEEDS} clean recordings ({:.1} %) {list:?}",
            100.0 * n as f64 / SEEDS as f64
        );
        assert!(n as f64 <= 0.05 * SEEDS as f64, "{m:?}: {list:?}");
        total += n;
    }
    println!(
        "both machines: {total} false alarms in {} recordings ({:.1} %)",
        2 * SEEDS,
        100.0 * total as f64 / (2 * SEEDS) as f64
    );
}
