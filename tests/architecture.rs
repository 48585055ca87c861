//! docs/ARCHITECTURE.md held against the code: what each module imports
//! (its table row, exactly, and only modules above it), where `unsafe`
//! lives, and that no message of the library names a command-line flag.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Modules every module may use; the table gives their own imports.
const FOUNDATION: [&str; 5] = ["error", "geom", "processor", "progress", "setting_names"];

/// The command line (the binary's `main.rs` and the library's
/// `command_line/`, which the Python package's command runs too): alone
/// names settings by their flags.
const COMMAND_LINE: [&str; 2] = ["src/main.rs", "src/command_line/"];

/// Files at the OS boundary, where `unsafe` may be (each with `// SAFETY:`),
/// and the processor's: the one place kernels compiled for instructions
/// the processor is asked about at run time are called.
const UNSAFE_AT: [&str; 7] = [
    "src/io/source/",
    "src/io/mmap_guard.rs",
    "src/io/mapped_file.rs",
    "src/command_line/mod.rs",
    "src/command_line/os_memory.rs",
    "src/processor.rs",
    "src/resample/bilinear_u8/dispatch.rs",
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The library's modules, as lib.rs declares them: the inner ones in
/// `inner_modules!`, the others one a line (`mod m;`, `pub mod m;`).
fn modules() -> Vec<String> {
    let lib = std::fs::read_to_string(root().join("src/lib.rs")).unwrap();
    let inner = lib.split("inner_modules! {").nth(1).expect("the inner modules").split('}').next().unwrap();
    let mut modules: Vec<String> = inner.split(',').map(|m| m.trim().to_string()).filter(|m| !m.is_empty()).collect();
    for line in lib.lines() {
        if let Some(m) = line.strip_prefix("pub mod ").or_else(|| line.strip_prefix("mod ")).and_then(|m| m.strip_suffix(';')) {
            modules.push(m.to_string());
        }
    }
    modules
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// A module's files: `src/m.rs` and everything under `src/m/`.
fn files_of(module: &str) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let single = root().join(format!("src/{module}.rs"));
    if single.exists() {
        files.push(single);
    }
    let dir = root().join(format!("src/{module}"));
    if dir.is_dir() {
        rust_files(&dir, &mut files);
    }
    files
}

/// A file's code without its unit tests (a trailing `mod tests`).
fn code_of(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    match text.find("#[cfg(test)]\nmod tests") {
        Some(k) => text[..k].to_string(),
        None => text,
    }
}

fn identifier(s: &str) -> &str {
    let end = s.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(s.len());
    &s[..end]
}

/// The crate's top-level names a file's code reaches: `crate::x::…` and
/// each item of `crate::{x, y::…}`.
fn crate_names(code: &str) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    let mut rest = code;
    while let Some(k) = rest.find("crate::") {
        rest = &rest[k + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            // The group's items at its own depth.
            let (mut depth, mut item_start) = (0usize, 0usize);
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => {
                        names.insert(identifier(group[item_start..].trim_start()).to_string());
                        break;
                    }
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        names.insert(identifier(group[item_start..].trim_start()).to_string());
                        item_start = i + 1;
                    }
                    _ => {}
                }
            }
        } else {
            names.insert(identifier(rest).to_string());
        }
    }
    names.remove("");
    names
}

/// The table of docs/ARCHITECTURE.md's "What may import what": each
/// module's row in order, with the modules it imports (parenthesised
/// notes left out).
fn table(modules: &[String]) -> Vec<(Vec<String>, BTreeSet<String>)> {
    let doc = std::fs::read_to_string(root().join("docs/ARCHITECTURE.md")).unwrap();
    let section = doc.split("## What may import what").nth(1).expect("the section").split("\n## ").next().unwrap();
    let ticked = |s: &str| -> Vec<String> {
        let mut out = Vec::new();
        let mut parts = s.split('`');
        parts.next();
        while let (Some(name), Some(_)) = (parts.next(), parts.next()) {
            out.push(name.to_string());
        }
        out
    };
    let without_notes = |s: &str| -> String {
        let mut out = String::new();
        let mut depth = 0;
        for c in s.chars() {
            match c {
                '(' => depth += 1,
                ')' => depth -= 1,
                _ if depth == 0 => out.push(c),
                _ => {}
            }
        }
        out
    };
    let mut rows = Vec::new();
    for line in section.lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = line.split('|').collect();
        let who = ticked(cells[1]);
        let imports: BTreeSet<String> = ticked(&without_notes(cells[2])).into_iter().filter(|m| modules.contains(m)).collect();
        rows.push((who, imports));
    }
    rows
}

#[test]
fn each_module_imports_what_its_row_says_and_only_modules_above_it() {
    let modules = modules();
    let rows = table(&modules);
    let mut row_of: BTreeMap<String, usize> = BTreeMap::new();
    for (k, (who, _)) in rows.iter().enumerate() {
        for m in who {
            assert!(row_of.insert(m.clone(), k).is_none(), "`{m}` has two rows in ARCHITECTURE.md");
        }
    }
    let mut wrong = Vec::new();
    for m in &modules {
        let Some(&k) = row_of.get(m) else {
            wrong.push(format!("`{m}` has no row in ARCHITECTURE.md's table"));
            continue;
        };
        let mut used: BTreeSet<String> = BTreeSet::new();
        for f in files_of(m) {
            used.extend(crate_names(&code_of(&f)));
        }
        // A foundation module is listed only in the foundation's rows.
        let listed_here = |u: &str| !FOUNDATION.contains(&u) || FOUNDATION.contains(&m.as_str());
        used.retain(|u| modules.contains(u) && u != m && listed_here(u));
        let listed = &rows[k].1;
        if &used != listed {
            wrong.push(format!("`{m}`: the code imports {:?}, its row says {:?}", used.iter().collect::<Vec<_>>(), listed.iter().collect::<Vec<_>>()));
        }
        for l in listed {
            if row_of.get(l).is_none_or(|&r| r >= k) {
                wrong.push(format!("`{m}` imports `{l}`, which is not above it in the table"));
            }
        }
    }
    assert!(wrong.is_empty(), "ARCHITECTURE.md and the code disagree:\n{}", wrong.join("\n"));
}

#[test]
fn the_import_reader_reads_groups_and_paths() {
    let code = "use crate::{camera::{self, Camera}, dem::mosaic, io};\nlet x = crate::options::Kernel::Bilinear;\nuse crate::gcm::Gcm;";
    let got: Vec<String> = crate_names(code).into_iter().collect();
    assert_eq!(got, ["camera", "dem", "gcm", "io", "options"]);
}

/// `unsafe` only at the OS boundary, each use said safe by a comment.
#[test]
fn unsafe_lives_only_at_the_os_boundary() {
    let mut files = Vec::new();
    rust_files(&root().join("src"), &mut files);
    rust_files(&root().join("python/src"), &mut files);
    let mut wrong = Vec::new();
    for f in files {
        let rel = f.strip_prefix(root()).unwrap().to_string_lossy().replace('\\', "/");
        let text = std::fs::read_to_string(&f).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (n, line) in lines.iter().enumerate() {
            let code = line.split("//").next().unwrap();
            if !(code.contains("unsafe {") || code.contains("unsafe fn") || code.contains("unsafe impl") || code.contains("unsafe extern")) {
                continue;
            }
            if !UNSAFE_AT.iter().any(|a| rel.starts_with(a)) {
                wrong.push(format!("{rel}:{}: unsafe outside the OS boundary", n + 1));
            }
            if !lines[n.saturating_sub(8)..n].iter().any(|l| l.trim_start().starts_with("// SAFETY:")) {
                wrong.push(format!("{rel}:{}: unsafe without a // SAFETY: comment above it", n + 1));
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// Whether `text` (a string literal's) names a flag (` --name`) other
/// than in a command line it quotes (`gcm-ortho fiducials --turn …`).
fn names_a_flag(text: &str) -> bool {
    let bytes = text.as_bytes();
    let mut from = 0;
    while let Some(k) = text[from..].find("--") {
        let at = from + k;
        from = at + 2;
        let starts_word = at == 0 || matches!(bytes[at - 1], b' ' | b'(' | b'`' | b'\'');
        let letter = bytes.get(at + 2).is_some_and(|c| c.is_ascii_lowercase());
        let quoted_command = ["gcm-ortho ", "projsync ", "gdal_translate "].iter().any(|c| text[..at].contains(c));
        if starts_word && letter && !quoted_command {
            return true;
        }
    }
    false
}

/// The string literals of a line of code (a rough reading: enough for
/// one-line literals and the lines of a long one).
fn literals(line: &str) -> Vec<&str> {
    let code = line.trim_start();
    if code.starts_with("//") {
        return Vec::new();
    }
    let parts: Vec<&str> = line.split('"').collect();
    parts.iter().skip(1).step_by(2).copied().collect()
}

/// The library names a setting by its key (`‹dem_hole›`): only the binary
/// turns keys into flags.
#[test]
fn no_message_of_the_library_names_a_flag() {
    let mut files = Vec::new();
    rust_files(&root().join("src"), &mut files);
    let mut wrong = Vec::new();
    for f in files {
        let rel = f.strip_prefix(root()).unwrap().to_string_lossy().replace('\\', "/");
        if COMMAND_LINE.iter().any(|c| rel.starts_with(c)) {
            continue;
        }
        for (n, line) in code_of(&f).lines().enumerate() {
            if literals(line).iter().any(|l| names_a_flag(l)) {
                wrong.push(format!("{}:{}: {}", f.strip_prefix(root()).unwrap().display(), n + 1, line.trim()));
            }
        }
    }
    assert!(wrong.is_empty(), "library messages naming flags (write ‹key› instead):\n{}", wrong.join("\n"));
}

#[test]
fn flags_are_told_from_other_dashes() {
    assert!(names_a_flag("give --memory 512M"));
    assert!(names_a_flag("(--dem-hole HEIGHT)"));
    assert!(!names_a_flag("give ‹memory› 512M"));
    assert!(!names_a_flag("/data/a--b.tif: -- bad"));
    assert!(!names_a_flag("measure them with `gcm-ortho fiducials --turn 90`"));
}

/// The API is what lib.rs exports: besides the inner modules (public only
/// under the `internals` feature) it opens only `options` and `by_key`.
#[test]
fn the_library_opens_only_its_api() {
    let lib = std::fs::read_to_string(root().join("src/lib.rs")).unwrap();
    let outside_the_macro =
        lib.split("macro_rules! inner_modules").next().unwrap().to_string() + lib.split("inner_modules! {").nth(1).unwrap().split_once('}').unwrap().1;
    let open: Vec<&str> = outside_the_macro.lines().filter_map(|l| l.strip_prefix("pub mod ")).map(|m| m.trim_end_matches([';', ' ', '{'])).collect();
    assert_eq!(open, ["options", "by_key"]);
    let inner = lib.split("macro_rules! inner_modules").nth(1).unwrap().split("inner_modules! {").next().unwrap();
    assert!(
        inner.contains("#[cfg(feature = \"internals\")]\n        pub mod $module;")
            && inner.contains("#[cfg(not(feature = \"internals\"))]\n        pub(crate) mod $module;")
    );
}
