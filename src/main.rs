//! The `kinpost` binary: parses the command line and hands over to the library.

use clap::Parser;

fn main() {
    let cli = kinpost::cli::Cli::parse();
    kinpost::output::remove_temporaries_on_signal();
    kinpost::cli::use_this_thread_as_worker();
    if let Err(e) = kinpost::cli::run(cli) {
        // A reader that stopped early (`kinpost post p.nc | head`) is not an
        // error of ours: stop quietly, as other filters do.
        if e.is_broken_pipe() {
            std::process::exit(kinpost::error::exit::OK);
        }
        eprintln!("kinpost: error: {e}");
        std::process::exit(e.exit_code());
    }
}
