//! The library's texts with each setting said as the flag that sets it in
//! the command that runs (`‹dem_hole›` → `--dem-hole`): warnings, reports.

/// The subcommand this process runs, set once by the command line.
static COMMAND: std::sync::OnceLock<String> = std::sync::OnceLock::new();

/// A text of the library (a warning, a report) with each setting it names
/// said as this command's flag (`‹dem_hole›` → `--dem-hole`).
pub fn with_flags(text: &str) -> String {
    let command = COMMAND.get().map(String::as_str).unwrap_or_default();
    crate::setting_names::name_settings(text, &|key| super::cli::flag_of(command, key))
}

/// Says a warning of the library on standard error, its settings as flags.
pub fn warn(text: &str) {
    eprintln!("gcm-ortho: warning: {}", with_flags(text));
}

/// Remembers the subcommand that runs (its first call wins).
pub fn set_command(command: &str) {
    let _ = COMMAND.set(command.to_string());
}
