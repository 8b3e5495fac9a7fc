//! The `vibroscope` command line: flag parsing and printing only. Each
//! command (`src/cmd/<command>.rs`) turns its flags into the options of a
//! recipe of the `vibroscope` library, calls it, and prints what it wrote
//! and a short summary.
//!
//! Exit status (the one table, [`vibroscope::ErrorKind::exit_code`]):
//!
//! | exit | meaning                                                        |
//! |------|----------------------------------------------------------------|
//! | 0    | success                                                        |
//! | 1    | runtime error (a stage failed, a file could not be read)       |
//! | 2    | usage or configuration error (a flag, a value, a file's content) |
//! | 130  | interrupted by Ctrl-C / SIGINT (outputs were finalised)        |
//! | 143  | interrupted by SIGTERM (outputs were finalised)                |
//! | 129  | interrupted by SIGHUP (outputs were finalised)                 |
//! | 0    | stdout closed early (`vibroscope pipelines \| head -1`)         |

mod cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;
use std::sync::atomic::{AtomicI32, Ordering};
use vibroscope::ErrorKind;

const EXIT_STATUS_HELP: &str = "Exit status: 0 success; 1 runtime error (a stage failed, a file \
    could not be read or written); 2 usage or configuration error (a flag, a value, a pipeline, \
    scene or input file); 130, 143, 129 interrupted by Ctrl-C, SIGTERM, SIGHUP (outputs were \
    finalised with what was processed).";

#[derive(Parser)]
#[command(
    name = "vibroscope",
    version,
    about = "Hear and measure vibration through a camera: a streaming visual-vibration engine",
    long_about = "Hear and measure vibration through a camera.\n\n\
        vibroscope runs pipelines of stages (sources, analysis, sinks) joined by bounded \
        ring buffers, on live cameras or on recordings (Y4M, Phantom .cine, Photron \
        .mraw/.cih, anything ffmpeg reads). Pipelines are TOML files; the shipped ones \
        run by name.\n\n\
        Start with `vibroscope demo` (no camera or file needed), then \
        `vibroscope pipelines` and `vibroscope probe FILE`.\n\n\
        Common flags: -o/--output is a command's main output; --json PATH writes JSON to \
        PATH; --fps HZ gives the capture rate (containers such as MP4 often state a \
        playback rate instead); --roi X,Y,W,H, --mask FILE and --pyramid csp|riesz choose \
        what is analysed.",
    after_help = EXIT_STATUS_HELP
)]
struct Cli {
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    Run(cmd::run::Args),
    Pipelines(cmd::pipelines::Args),
    Kinds(cmd::kinds::Args),
    Probe(cmd::probe::Args),
    Bound(cmd::bound::Args),
    Listen(cmd::listen::Args),
    Magnify(cmd::magnify::Args),
    #[command(name = "rs-calibrate")]
    RsCalibrate(cmd::rs_calibrate::Args),
    Score(cmd::score::Args),
    Pitch(cmd::pitch::Args),
    Simulate(cmd::simulate::Args),
    Devices(cmd::devices::Args),
    Record(cmd::record::Args),
    Calibrate(cmd::calibrate::Args),
    Spectrum(cmd::spectrum::Args),
    Modes(cmd::modes::Args),
    Idv(cmd::idv::Args),
    Rod(cmd::rod::Args),
    Compare(cmd::compare::Args),
    Demo(cmd::demo::Args),
    Learn(cmd::learn::Args),
    Studio(cmd::studio::Args),
    #[cfg(feature = "net")]
    Monitor(cmd::monitor::Args),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() {
                ErrorKind::Usage.exit_code()
            } else {
                0
            };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    init_tracing(cli.verbose);
    install_signals();
    let result = run(cli.command);
    if let Some(e) = cmd::stdout_error() {
        // A reader that closed the pipe (`| head -1`) has what it wanted:
        // end quietly with the command's own status. Any other failure
        // (a full disk, `> /dev/full`) lost output: say so and exit 1.
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            eprintln!("error: cannot write to stdout: {e}");
            if result.is_ok() {
                return ExitCode::from(ErrorKind::Runtime.exit_code());
            }
        }
    }
    match result {
        Ok(code) => code,
        Err(e) => {
            let kind = vibroscope::error::kind_of(e.as_ref());
            if kind == ErrorKind::Interrupted {
                eprintln!("{e:#}");
                return ExitCode::from(interrupted_exit_code());
            }
            eprintln!("error: {e:#}");
            ExitCode::from(kind.exit_code())
        }
    }
}

fn run(command: Command) -> anyhow::Result<ExitCode> {
    match command {
        Command::Run(a) => cmd::run::run(a),
        Command::Pipelines(a) => cmd::pipelines::run(a),
        Command::Kinds(a) => cmd::kinds::run(a),
        Command::Probe(a) => cmd::probe::run(a),
        Command::Bound(a) => cmd::bound::run(a),
        Command::Listen(a) => cmd::listen::run(a),
        Command::Magnify(a) => cmd::magnify::run(a),
        Command::RsCalibrate(a) => cmd::rs_calibrate::run(a),
        Command::Score(a) => cmd::score::run(a),
        Command::Pitch(a) => cmd::pitch::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Devices(a) => cmd::devices::run(a),
        Command::Record(a) => cmd::record::run(a),
        Command::Calibrate(a) => cmd::calibrate::run(a),
        Command::Spectrum(a) => cmd::spectrum::run(a),
        Command::Modes(a) => cmd::modes::run(a),
        Command::Idv(a) => cmd::idv::run(a),
        Command::Rod(a) => cmd::rod::run(a),
        Command::Compare(a) => cmd::compare::run(a),
        Command::Demo(a) => cmd::demo::run(a),
        Command::Learn(a) => cmd::learn::run(a),
        Command::Studio(a) => cmd::studio::run(a),
        #[cfg(feature = "net")]
        Command::Monitor(a) => cmd::monitor::run(a),
    }
}

fn init_tracing(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    use std::io::IsTerminal;
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .try_init();
}

/// The signal that interrupted the run (0: none), for the exit status
/// 128 + signal (130 SIGINT, 143 SIGTERM, 129 SIGHUP).
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// Exit status of an interruption: 128 + the signal's number (130 when
/// none was recorded, e.g. Ctrl-C on a platform without signal numbers).
fn interrupted_exit_code() -> u8 {
    match SIGNAL.load(Ordering::SeqCst) {
        n @ 1..=127 => 128 + n as u8,
        _ => ErrorKind::Interrupted.exit_code(),
    }
}

/// What the first, second and third interruption do (Ctrl-C, SIGTERM and
/// SIGHUP alike): stop the sources and drain, then stop at once (sinks
/// still finalise), then exit. With no run under way the first one asks
/// a recipe that checks between its steps to stop at the next one
/// (`vibroscope::pipeline::Steps`), and otherwise exits at once (files are
/// written whole by a rename, so none is left half written).
fn on_interrupt(presses: usize) {
    match presses {
        0 if vibroscope::pipeline::stop_current() => {
            eprintln!(
                "\nstopping: draining queues and finalising outputs (interrupt again to stop at once)"
            );
        }
        0 if vibroscope::pipeline::interrupt() => {
            eprintln!("\nstopping after the current step (interrupt again to exit at once)");
        }
        1 if vibroscope::pipeline::abort_current() => {}
        _ => std::process::exit(interrupted_exit_code().into()),
    }
}

/// SIGINT, SIGTERM and SIGHUP go to [`on_interrupt`] from a thread of their
/// own (signal-hook's self-pipe), so the handler may lock and print.
#[cfg(unix)]
fn install_signals() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
        eprintln!("warning: cannot install the signal handlers; an interruption will not finalise outputs");
        return;
    };
    std::thread::spawn(move || {
        for (presses, sig) in signals.forever().enumerate() {
            let _ = SIGNAL.compare_exchange(0, sig, Ordering::SeqCst, Ordering::SeqCst);
            on_interrupt(presses);
        }
    });
}

#[cfg(not(unix))]
fn install_signals() {
    static PRESSES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let _ = ctrlc::set_handler(|| on_interrupt(PRESSES.fetch_add(1, Ordering::SeqCst)));
}
