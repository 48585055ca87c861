//! The binary: the command line (`command_line`) over the library.

#[macro_use]
mod quiet_print;
mod cli;
mod command_line;
mod commands;
mod flag_names;
mod progress_bar;

fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(command_line::run(std::env::args_os().collect()))
}
