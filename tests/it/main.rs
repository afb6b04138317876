//! The integration tests, one binary (linking ~48 binaries was slow):
//! one module per former `tests/*.rs` file, helpers in `util` and the
//! helper modules of the diagnose, G-code differential and seed 003 tests.
//! Snapshots are in `tests/it/snapshots/` (named `it__<module>__<name>`),
//! proptest regressions in `tests/proptest-regressions/<module>.txt`.

mod util;

mod cl_support;
mod diagnose_support;
mod gcode_reference;
mod seed003_tables;

mod analyze_plot;
mod architecture;
mod bad_input;
mod cl;
mod cl_cutcom;
mod cl_dialects;
mod cl_driver;
mod cl_part_programs;
mod cl_real;
mod cl_words;
mod cli_corpus_echo;
mod cli_diagnose;
mod cli_help;
mod cli_machine;
mod compensate_robust;
mod compensate_stream;
mod corpus_roundtrip;
mod demo_fixtures;
mod diagnose_clock_rate;
mod diagnose_csv_dialects;
mod diagnose_docs;
mod diagnose_effects;
mod diagnose_error_motion;
mod diagnose_false_alarm;
mod diagnose_feedback;
mod diagnose_feedback_rate;
mod diagnose_loop;
mod diagnose_registration;
mod diagnose_report;
mod diagnose_sampling;
mod diagnose_thermal;
mod diagnose_untidy;
mod diagnose_vibration;
mod diagnose_wander;
mod fifth_hunt;
mod filter_corpus;
mod fit;
mod fit_cache;
mod fit_fixtures;
mod freecad_wrapper;
mod gcode_differential;
mod gcode_parse;
mod gcode_proptest;
mod gcode_snapshot;
mod grammar;
mod heidenhain;
mod integration_docs;
mod inverse_time;
mod job_setup;
mod kinematics_continuity;
mod kinematics_file;
mod kinematics_near_axis;
mod kinematics_programs;
mod kinematics_props;
mod kinematics_wang;
mod linkage_fixtures;
mod linkage_words;
mod linuxcnc_import;
mod machine_moves;
mod modal_axes;
mod model_file_strict;
mod not_tool_vectors;
mod output_safety;
mod panic_cleanup;
mod parse_throughput;
mod post;
mod robustness_parse;
mod scenarios;
mod seed000;
mod seed003;
mod simulate_arcs;
mod simulate_stream;
mod sixth_hunt;
mod valid_jobs;
mod wrapped_rotary;
