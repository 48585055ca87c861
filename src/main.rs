//! The binary: the library's command line.

fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(gcm_ortho::run_command_line(std::env::args_os().collect()))
}
