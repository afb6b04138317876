//! The `kinpost` binary: parses the command line and hands over to the library.

use clap::Parser;

fn main() {
    let cli = kinpost::cli::Cli::parse();
    kinpost::cli::use_this_thread_as_worker();
    if let Err(e) = kinpost::cli::run(cli) {
        eprintln!("kinpost: error: {e}");
        std::process::exit(e.exit_code());
    }
}
