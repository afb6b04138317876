//! The `kinpost` binary: the command line (clap, `cli/`) over the library's
//! capabilities. The command-line layer is the binary's own: the library
//! exports what kinpost can do, not how the command line spells it.

use clap::Parser;

// The library's modules the command line uses, named at the root of the
// binary so that the command-line code reaches them as `crate::…` (new
// ones are added here).
use kinpost::{
    analyze, cl, compensate, diagnose, error, gcode, geometric, input, json_stream, linkage,
    machine, numeric, output, post, program, progress, report, text, trajectory,
};

mod cli;

fn main() {
    let cli = cli::Cli::parse();
    kinpost::output::remove_temporaries_on_signal();
    kinpost::output::remove_temporaries_on_panic();
    cli::use_this_thread_as_worker();
    if let Err(e) = cli::run(cli) {
        // A reader that stopped early (`kinpost post p.nc | head`) is not an
        // error of ours: stop quietly, as other filters do.
        if e.is_broken_pipe() {
            std::process::exit(kinpost::error::exit::OK);
        }
        eprintln!("kinpost: error: {e}");
        std::process::exit(e.exit_code());
    }
}
