use std::process::ExitCode;

fn main() -> ExitCode {
    vibroscope::cli::main()
}
