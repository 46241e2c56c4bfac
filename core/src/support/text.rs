//! Untrusted text (a CSV cell, a column or contact name) as messages and outputs show it.

/// How many characters of untrusted text a message shows.
pub const SHOWN_CHARS: usize = 80;

/// `text` as it is safe to print: its [hidden](is_hidden) characters (terminal escapes, new
/// lines, bidirectional overrides) written visibly as Rust escapes (`\u{1b}`, `\n`), and cut to [`SHOWN_CHARS`] characters with `…` when longer, so that a cell can
/// neither drive the user's terminal nor flood it. Quotes and backslashes stay as written.
pub fn shown(text: &str) -> String {
    let mut out = String::new();
    let mut count = 0;
    for c in text.chars() {
        let escaped = is_hidden(c);
        for p in c.escape_debug().filter(|_| escaped).chain((!escaped).then_some(c)) {
            if count == SHOWN_CHARS {
                out.push('…');
                return out;
            }
            out.push(p);
            count += 1;
        }
    }
    out
}

/// Whether `c` prints as something else than itself, or changes how the text around it
/// prints: a control character (terminal escapes start with one) or an invisible formatting
/// character (zero-width spaces, bidirectional overrides). What [`shown`] escapes.
pub fn is_hidden(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{200b}'..='\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}' | '\u{feff}')
}

/// Why a name read from a user's file (a fixed point's, a plane's, a station's, a group's)
/// cannot be one: a hidden character, or more than [`SHOWN_CHARS`] characters, so that every
/// message and output can show the name whole and as it is.
pub fn check_name(name: &str) -> Result<(), String> {
    if let Some(c) = name.chars().find(|c| is_hidden(*c)) {
        return Err(format!(
            "`{}` holds the character {}; a name is printable text",
            shown(name),
            c.escape_debug()
        ));
    }
    let n = name.chars().count();
    if n > SHOWN_CHARS {
        return Err(format!(
            "`{}` is {n} characters long; a name has at most {SHOWN_CHARS}",
            shown(name)
        ));
    }
    Ok(())
}

/// A number a user gave, as a message shows it: its shortest digits that read back the same,
/// in scientific notation when very small or very large (`1e-308`, not 308 zeros).
pub fn number(v: f64) -> String {
    if v.is_finite() && v != 0.0 && !(1e-4..1e15).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_shown_short_and_read_back_the_same() {
        assert_eq!(number(1e-308), "1e-308");
        assert_eq!(number(2.5e20), "2.5e20");
        assert_eq!(number(0.1), "0.1");
        assert_eq!(number(-1500.25), "-1500.25");
        assert_eq!(number(f64::NAN), "NaN");
        for v in [1e-308, 3.3e-5, 0.1, 123.456, 7e18] {
            assert_eq!(number(v).parse::<f64>().unwrap(), v);
        }
    }

    #[test]
    fn plain_text_is_shown_as_it_is() {
        assert_eq!(shown("hole_1"), "hole_1");
        assert_eq!(shown("x[mm]"), "x[mm]");
        assert_eq!(shown(""), "");
        assert_eq!(shown(r#"3" "it's" C:\d"#), r#"3" "it's" C:\d"#);
    }

    #[test]
    fn control_characters_are_shown_escaped() {
        let s = shown("\u{1b}]0;PWNED\u{7}\u{1b}[31mRED\n\u{202e}");
        assert!(!s.chars().any(char::is_control), "{s:?}");
        assert_eq!(s, "\\u{1b}]0;PWNED\\u{7}\\u{1b}[31mRED\\n\\u{202e}");
    }

    #[test]
    fn names_must_be_printable_and_short() {
        assert!(check_name("hole_1").is_ok());
        assert!(check_name("plaque à trous").is_ok());
        let m = check_name("a\u{1b}[31m").unwrap_err();
        assert!(m.contains("\\u{1b}") && !m.contains('\u{1b}'), "{m}");
        let m = check_name(&"n".repeat(81)).unwrap_err();
        assert!(m.contains("81 characters"), "{m}");
        assert!(check_name(&"n".repeat(80)).is_ok());
    }

    #[test]
    fn long_text_is_cut_to_its_bound() {
        let long = "a".repeat(10_000);
        let s = shown(&long);
        assert_eq!(s.chars().count(), SHOWN_CHARS + 1);
        assert!(s.ends_with('…'));
        // Exactly the bound is not cut.
        assert_eq!(shown(&long[..SHOWN_CHARS]), long[..SHOWN_CHARS]);
        // Escapes count as the characters they print.
        let escapes = shown(&"\u{1b}".repeat(100));
        assert_eq!(escapes.chars().count(), SHOWN_CHARS + 1);
        assert!(!escapes.chars().any(char::is_control));
    }
}
