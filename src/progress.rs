//! Progress on stderr, whether or not stdout is a terminal: indicatif's bars when stderr is a
//! terminal, otherwise plain lines (the bar's text without the bar, at most one every few
//! seconds) so that a log or a pipe shows that a long command is alive and how far it is.

use std::io::{self, IsTerminal};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle, TermLike};

/// The least time between two plain progress lines.
const LINE_EVERY: Duration = Duration::from_secs(5);

/// Seconds per stage (`geometry 12.1 s · …`) and the memory the process holds now (its
/// resident set, where the platform tells it), for a long search's progress line.
pub fn stages_and_memory(stages: &[(&str, f64)]) -> String {
    let mut parts: Vec<String> = stages.iter().map(|(what, s)| format!("{what} {s:.1} s")).collect();
    if let Some(m) = memory_stats::memory_stats() {
        parts.push(format!("{} MiB held", m.physical_mem >> 20));
    }
    parts.join(" · ")
}

/// A progress display of `len` steps (`None`: a count without a total) drawn with `template`
/// (indicatif's syntax; a `{bar}` or `{spinner}` in it is left out of plain lines).
pub fn bar(len: Option<u64>, template: &str) -> ProgressBar {
    let (target, template) = if io::stderr().is_terminal() {
        (ProgressDrawTarget::stderr(), template.to_string())
    } else {
        // Two draws a second at most reach the lines' own limit: formatting a line per update
        // of a fast loop would cost more than it shows.
        (
            ProgressDrawTarget::term_like_with_hz(Box::new(PlainLines::default()), 2),
            without_bar(template),
        )
    };
    let bar = ProgressBar::with_draw_target(len, target);
    bar.set_style(ProgressStyle::with_template(&template).expect("the template is valid"));
    bar
}

/// `template` without its bar and spinner placeholders (and the brackets around them), its
/// spaces collapsed.
fn without_bar(template: &str) -> String {
    let mut out = String::with_capacity(template.len());
    let mut rest = template;
    while let Some(start) = rest.find('{') {
        let Some(len) = rest[start..].find('}') else {
            break;
        };
        let field = &rest[start + 1..start + len];
        let name = field.split([':', '.']).next().unwrap_or_default();
        out.push_str(&rest[..start]);
        if name != "bar" && name != "wide_bar" && name != "spinner" {
            out.push_str(&rest[start..=start + len]);
        }
        rest = &rest[start + len + 1..];
    }
    out.push_str(rest);
    out.replace("[]", "").split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A "terminal" that prints each drawn state as one line on stderr, at most one every
/// [`LINE_EVERY`] and never the same line twice in a row; cursor moves and clears, which only
/// a terminal can honour, do nothing.
#[derive(Debug, Default)]
struct PlainLines(Mutex<Lines>);

#[derive(Debug, Default)]
struct Lines {
    /// What the current draw wrote so far.
    pending: String,
    /// When the last line was printed, and what it said.
    printed: Option<(Instant, String)>,
}

impl TermLike for PlainLines {
    fn width(&self) -> u16 {
        // Wide enough that indicatif never wraps a line (the padding is trimmed).
        500
    }

    fn move_cursor_up(&self, _: usize) -> io::Result<()> {
        Ok(())
    }

    fn move_cursor_down(&self, _: usize) -> io::Result<()> {
        Ok(())
    }

    fn move_cursor_right(&self, _: usize) -> io::Result<()> {
        Ok(())
    }

    fn move_cursor_left(&self, _: usize) -> io::Result<()> {
        Ok(())
    }

    fn write_line(&self, s: &str) -> io::Result<()> {
        self.write_str(s)?;
        self.write_str("\n")
    }

    fn write_str(&self, s: &str) -> io::Result<()> {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .pending
            .push_str(s);
        Ok(())
    }

    fn clear_line(&self) -> io::Result<()> {
        Ok(())
    }

    fn flush(&self) -> io::Result<()> {
        let mut lines = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        let drawn = std::mem::take(&mut lines.pending);
        let line = drawn
            .split(['\r', '\n'])
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .collect::<Vec<_>>()
            .join(" ");
        let due = match &lines.printed {
            None => true,
            Some((at, last)) => at.elapsed() >= LINE_EVERY && *last != line,
        };
        if due && !line.is_empty() {
            eprintln!("{line}");
            lines.printed = Some((Instant::now(), line));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::without_bar;

    #[test]
    fn plain_lines_keep_the_counts_and_drop_the_bar() {
        assert_eq!(
            without_bar("calibrating {bar:30} {pos}/{len} iterations  {msg}"),
            "calibrating {pos}/{len} iterations {msg}"
        );
        assert_eq!(
            without_bar("{msg:>12} [{bar:30}] {pos}/{len} {elapsed_precise}"),
            "{msg:>12} {pos}/{len} {elapsed_precise}"
        );
        assert_eq!(
            without_bar("learning curves {spinner} {pos} fits  {elapsed}"),
            "learning curves {pos} fits {elapsed}"
        );
    }
}
