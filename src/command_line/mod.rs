//! The command line's edge: parse arguments, run, print one readable
//! error line, map errors to exit codes. `anyhow` lives only here and in
//! the commands. Built into the binary and into the Python package's
//! `gcm-ortho` command.

#[macro_use]
mod quiet_print;
mod cli;
mod commands;
mod flag_names;
mod os_memory;
mod progress_bar;

use clap::Parser;

/// glibc gives threads that allocate arenas of their own, up to eight a
/// core, and each keeps what is freed in it: a mosaic's image threads left
/// some 100 MB freed but resident. Half as many arenas as cores (two at
/// least) keep the peak near the live heap, at the same speed.
///
/// And glibc raises the size it maps a block of memory at on its own to
/// the largest block freed (up to 32 MB): the buffers of bands and chunks
/// then come from the arenas, whose holes between them stay resident (the
/// 1 GB panoramic strip at --memory 128M: 153 MiB peak for 118 MB of
/// heap). A fixed 1 MiB returns every large block when it is freed (129 MB).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn tune_malloc() {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    // SAFETY: mallopt only sets the allocator's tuning parameters; it is
    // called before any other thread starts.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, (cores / 2).max(2) as libc::c_int);
        libc::mallopt(libc::M_MMAP_THRESHOLD, 1 << 20);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn tune_malloc() {}

/// A usage error in one line, as every other error (clap's own layout is
/// five: the error, a tip, the usage, a pointer to --help); help and
/// version as clap prints them.
fn usage_error(e: clap::Error) -> u8 {
    use clap::error::ErrorKind;
    if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand) {
        e.exit();
    }
    let text = e.to_string();
    let mut said = String::new();
    let mut tips = Vec::new();
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if line.starts_with("Usage:") || line.starts_with("For more information") {
            continue;
        }
        if let Some(tip) = line.strip_prefix("tip:") {
            tips.push(tip.trim().to_string());
        } else if let Some(first) = line.strip_prefix("error:") {
            said.push_str(first.trim());
        } else {
            // The list under the first line (missing arguments, values).
            said.push_str(if said.ends_with(':') || line.starts_with('[') { " " } else { ", " });
            said.push_str(line);
        }
    }
    for tip in tips {
        said.push_str(&format!(" ({tip})"));
    }
    // A satellite image needs no camera file: its RPC does instead.
    if e.kind() == ErrorKind::MissingRequiredArgument && said.contains("--rpc <RPC>, --camera <CAMERA>") {
        said = said.replace(
            "--rpc <RPC>, --camera <CAMERA>",
            "--camera <CAMERA> or --rpc <RPC> (a satellite image's RPC file, or the image itself when it carries an RPC tag)",
        );
    } else if e.kind() == ErrorKind::MissingRequiredArgument && said.contains("--camera <CAMERA>") {
        said = said.replace("--camera <CAMERA>", "--camera <CAMERA> (or --rpc <RPC> for a satellite image)");
    }
    eprintln!("gcm-ortho: error: {said}; see --help");
    2
}

/// Runs the command line `args` (the program's name first); its exit code: 0
/// success, 1 bad input or failure, 2 usage, 3 a batch in which some jobs
/// failed, 130 SIGINT, 143 SIGTERM.
pub fn run(args: Vec<std::ffi::OsString>) -> u8 {
    tune_malloc();
    crate::io::publish::record_publications();
    let cli = match cli::Cli::try_parse_from(&args) {
        Ok(cli) => cli,
        Err(e) => return usage_error(e),
    };
    // Which subcommand ran, to name a setting by its flag where it has one.
    let command = args.get(1).map(|a| a.to_string_lossy().into_owned()).unwrap_or_default();
    flag_names::set_command(&command);
    cli::note_not_utf8(&args);
    let polls = matches!(
        cli.command,
        cli::Command::Rectify(_) | cli::Command::Batch(_) | cli::Command::Demo(_) | cli::Command::Mosaic(_) | cli::Command::Grid(_) | cli::Command::Dem(_)
    );
    let signals = match commands::Signals::install(polls) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("gcm-ortho: cannot install signal handlers: {e}");
            return 1;
        }
    };
    match commands::run(cli, &signals) {
        Ok(code) => code,
        Err(e) => {
            if let Some(code) = signals.exit_code() {
                if !signals.claim_end() {
                    // The watchdog is ending the process.
                    loop {
                        std::thread::park();
                    }
                }
                eprintln!("gcm-ortho: interrupted; no unfinished output was left behind");
                return code;
            }
            // Broken pipe on stdout is not an error worth a message.
            if e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)) {
                return 0;
            }
            // A setting named by its key is printed as the flag that sets it.
            let mut parts: Vec<String> = Vec::new();
            // An I/O error says its cause in words: not again as the OS does.
            let mut cause_said = false;
            for c in e.chain() {
                if std::mem::take(&mut cause_said) {
                    continue;
                }
                cause_said = matches!(c.downcast_ref::<crate::Error>(), Some(crate::Error::Io { .. }));
                let part = match c.downcast_ref::<crate::Error>() {
                    Some(e) => e.naming_settings(&|key| cli::flag_of(&command, key)),
                    None => c.to_string(),
                };
                // A cause its error already quotes is said once.
                if !parts.last().is_some_and(|p| p.ends_with(&part)) {
                    parts.push(part);
                }
            }
            let msg = parts.join(": ");
            eprintln!("gcm-ortho: error: {}", msg.replace('\n', " "));
            let usage = e.chain().any(|c| matches!(c.downcast_ref::<crate::Error>(), Some(crate::Error::Usage(_) | crate::Error::Setting { .. })));
            if usage {
                2
            } else {
                1
            }
        }
    }
}
