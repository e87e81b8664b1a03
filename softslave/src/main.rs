//! `pbcard-softslave`: see `--help` and the README section "Soft slave".

use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use pbcard_softslave::{parse_args, run, Command, USAGE};

fn main() -> ExitCode {
    let opts = match parse_args(std::env::args().skip(1)) {
        Ok(Command::Run(o)) => o,
        Ok(Command::Help) => {
            print!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        Ok(Command::Version) => {
            println!("pbcard-softslave {}", env!("CARGO_PKG_VERSION"));
            return ExitCode::SUCCESS;
        }
        Err(e) => {
            eprintln!("pbcard-softslave: {e}\n(try --help)");
            return ExitCode::from(2);
        }
    };
    // A bad station list (addresses, --config file) is one line and exit status 2, before the
    // device is opened.
    if let Err(e) = opts.stations() {
        eprintln!("pbcard-softslave: {e}");
        return ExitCode::from(2);
    }
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    if let Err(e) = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed)) {
        eprintln!("pbcard-softslave: cannot install the Ctrl-C handler: {e}");
        return ExitCode::FAILURE;
    }
    match run(&opts, &stop, &mut |line| println!("{line}")) {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("pbcard-softslave: {e}");
            ExitCode::FAILURE
        }
    }
}
