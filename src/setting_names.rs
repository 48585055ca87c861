//! A message of the library names a setting by its key between ‹ and ›
//! (`give ‹memory› 512M or more`), and whoever shows it names the setting as
//! its user gives it: the command line as a flag (`--memory`), a manifest or
//! Python as the key (`memory`). The library never says a flag.

/// `text` with each marked setting `‹key›` said by `name(key)`; anything
/// else between the marks (not a key's letters) is left as it is.
pub fn name_settings(text: &str, name: &dyn Fn(&str) -> String) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(open) = rest.find('‹') {
        let (before, marked) = rest.split_at(open);
        out.push_str(before);
        let inner = &marked['‹'.len_utf8()..];
        match inner.find('›') {
            Some(close) if is_key(&inner[..close]) => {
                out.push_str(&name(&inner[..close]));
                rest = &inner[close + '›'.len_utf8()..];
            }
            _ => {
                out.push('‹');
                rest = inner;
            }
        }
    }
    out.push_str(rest);
    out
}

/// `text` with each marked setting said by its key.
pub fn as_keys(text: &str) -> String {
    name_settings(text, &|key| key.to_string())
}

fn is_key(s: &str) -> bool {
    s.starts_with(|c: char| c.is_ascii_lowercase()) && s.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_are_named_as_asked() {
        let flag = |k: &str| format!("--{}", k.replace('_', "-"));
        let text = "give ‹memory› 512M or ‹dem_outside› HEIGHT";
        assert_eq!(name_settings(text, &flag), "give --memory 512M or --dem-outside HEIGHT");
        assert_eq!(as_keys(text), "give memory 512M or dem_outside HEIGHT");
    }

    #[test]
    fn other_text_between_marks_is_kept() {
        assert_eq!(as_keys("a ‹Not a key› and ‹› and ‹open"), "a ‹Not a key› and ‹› and ‹open");
        assert_eq!(as_keys("‹‹gsd››"), "‹gsd›");
    }
}
