//! The repository's Markdown stays readable and navigable: every code fence is closed, and every
//! relative link (`[x](path)`, `[x](path#anchor)`, `[x](#anchor)`) names a file that exists and,
//! into a Markdown file, a heading that exists under GitHub's anchor rule.

use std::collections::HashMap;
use std::fs;
use std::ops::Range;
use std::path::{Component, Path, PathBuf};

use pulldown_cmark::{CodeBlockKind, Event, Options, Parser, Tag, TagEnd};

use crate::common::root;

/// Every `.md` file under `dir`, skipping build output (`target/`) and hidden folders.
fn markdown_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut entries: Vec<_> = fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.expect("directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if path.is_dir() {
            if name != "target" && !name.starts_with('.') {
                files.extend(markdown_files(&path));
            }
        } else if name.ends_with(".md") {
            files.push(path);
        }
    }
    files
}

fn parser(text: &str) -> Parser<'_> {
    // GitHub-flavoured: tables, footnotes, strikethrough, task lists.
    let options =
        Options::ENABLE_TABLES | Options::ENABLE_FOOTNOTES | Options::ENABLE_STRIKETHROUGH | Options::ENABLE_TASKLISTS;
    Parser::new_ext(text, options)
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset].matches('\n').count() + 1
}

/// GitHub's anchor for a heading's text: lowercase, spaces to `-`, punctuation other than `-`
/// and `_` dropped.
fn slug(heading: &str) -> String {
    heading
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            '-' | '_' => Some(c),
            c if c.is_alphanumeric() => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a Markdown text's headings; a repeated slug gets `-1`, `-2`, ... as on GitHub.
fn anchors(text: &str) -> Vec<String> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut result = Vec::new();
    let mut heading: Option<String> = None;
    for event in parser(text) {
        match event {
            Event::Start(Tag::Heading { .. }) => heading = Some(String::new()),
            Event::Text(t) | Event::Code(t) => {
                if let Some(h) = heading.as_mut() {
                    h.push_str(&t);
                }
            }
            Event::End(TagEnd::Heading(_)) => {
                let base = slug(&heading.take().unwrap_or_default());
                let count = seen.entry(base.clone()).or_insert(0);
                result.push(if *count == 0 {
                    base.clone()
                } else {
                    format!("{base}-{count}")
                });
                *count += 1;
            }
            _ => {}
        }
    }
    result
}

/// A fenced block is closed when its last line is a fence of the opening's character, at least
/// as long (CommonMark); an unclosed one runs to the end of the file.
fn fence_closed(block: &str) -> bool {
    // Indentation of list items and block-quote markers are not part of a fence.
    fn strip(line: &str) -> &str {
        line.trim_start_matches([' ', '>']).trim_end()
    }
    let mut lines = block.trim_end_matches('\n').lines();
    let open = strip(lines.next().unwrap_or_default());
    let Some(fence) = open.chars().next() else {
        return false;
    };
    let width = open.chars().take_while(|&c| c == fence).count();
    let Some(last) = lines.last().map(strip) else {
        return false;
    };
    last.chars().all(|c| c == fence) && last.chars().count() >= width
}

fn is_external(dest: &str) -> bool {
    ["http://", "https://", "mailto:"]
        .iter()
        .any(|scheme| dest.starts_with(scheme))
}

/// `path` joined onto `dir` with `.` and `..` resolved lexically (the file may not exist).
fn resolve(dir: &Path, path: &str) -> PathBuf {
    let mut out = dir.to_path_buf();
    for part in Path::new(path).components() {
        match part {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// Every problem of one Markdown file, as `file:line: message`.
fn problems(file: &Path, text: &str) -> Vec<String> {
    let mut found = Vec::new();
    let shown = file.strip_prefix(root()).unwrap_or(file).display();
    let mut links: Vec<(String, Range<usize>)> = Vec::new();
    for (event, range) in parser(text).into_offset_iter() {
        match event {
            Event::Start(Tag::CodeBlock(CodeBlockKind::Fenced(_))) if !fence_closed(&text[range.clone()]) => {
                found.push(format!(
                    "{shown}:{}: code fence never closed",
                    line_of(text, range.start)
                ));
            }
            Event::Start(Tag::Link { dest_url, .. } | Tag::Image { dest_url, .. }) => {
                links.push((dest_url.to_string(), range));
            }
            _ => {}
        }
    }
    let dir = file.parent().expect("a file has a folder");
    for (dest, range) in links {
        if is_external(&dest) {
            continue;
        }
        let at = format!("{shown}:{}", line_of(text, range.start));
        let (path, anchor) = match dest.split_once('#') {
            Some((path, anchor)) => (path, Some(anchor)),
            None => (dest.as_str(), None),
        };
        let target = if path.is_empty() {
            file.to_path_buf()
        } else {
            resolve(dir, path)
        };
        if !path.is_empty() && !target.exists() {
            found.push(format!("{at}: link `{dest}`: {} does not exist", target.display()));
            continue;
        }
        let Some(anchor) = anchor else { continue };
        if target.extension().is_some_and(|e| e == "md") {
            let target_text = if path.is_empty() {
                text.to_string()
            } else {
                fs::read_to_string(&target).expect("a Markdown file reads")
            };
            if !anchors(&target_text).iter().any(|a| a == anchor) {
                found.push(format!(
                    "{at}: link `{dest}`: no heading of {} has the anchor `#{anchor}`",
                    target.display()
                ));
            }
        }
    }
    found
}

#[test]
fn every_markdown_file_closes_its_fences_and_its_relative_links_resolve() {
    let files = markdown_files(&root());
    for expected in ["README.md", "BENCHMARKS.md", "docs/ARCHITECTURE.md"] {
        assert!(
            files.contains(&root().join(expected)),
            "{expected} not among the Markdown files found"
        );
    }
    let all: Vec<String> = files
        .iter()
        .flat_map(|f| problems(f, &fs::read_to_string(f).expect("Markdown file reads")))
        .collect();
    assert!(all.is_empty(), "{} problem(s):\n{}", all.len(), all.join("\n"));
}

#[test]
fn slugs_follow_githubs_rule() {
    // Worked by hand from GitHub's rendering of these headings.
    assert_eq!(slug("Two commands"), "two-commands");
    assert_eq!(
        slug("Your own robot: TALOS from its ROS URDF"),
        "your-own-robot-talos-from-its-ros-urdf"
    );
    assert_eq!(
        slug("2b. Or build it as a run-time plugin"),
        "2b-or-build-it-as-a-run-time-plugin"
    );
    assert_eq!(
        slug("Real data: Agile Justin (src/agile_justin.rs)"),
        "real-data-agile-justin-srcagile_justinrs"
    );
    assert_eq!(slug("Torso's coupling, Bäuml"), "torsos-coupling-bäuml");
    // Code spans count as heading text; repeated headings are numbered.
    assert_eq!(
        anchors("# All methods of `armcomp plan`\n\n## Notes\n\n## Notes\n"),
        ["all-methods-of-armcomp-plan", "notes", "notes-1"]
    );
}

#[test]
fn the_check_finds_unclosed_fences_missing_files_and_missing_anchors() {
    let dir = tempfile::tempdir().unwrap();
    let other = dir.path().join("other.md");
    fs::write(&other, "# Other page\n\n## A section, with punctuation!\n").unwrap();
    let page = dir.path().join("page.md");
    let check = |text: &str| problems(&page, text);

    let good = "# Page\n\n[a](other.md) [b](other.md#a-section-with-punctuation) [c](#page)\n\
                [d](./other.md) [e](https://example.com/missing.md) [f](mailto:x@example.com)\n\n\
                ```sh\nls\n```\n\n~~~~\n```\n~~~~\n\n- item\n\n  ```toml\n  a = 1\n  ```\n";
    assert_eq!(check(good), Vec::<String>::new());

    let unclosed = "# Page\n\ntext\n\n```toml\na = 1\n\n## Not a heading\n";
    let found = check(unclosed);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].ends_with(":5: code fence never closed"), "{found:?}");

    // A closing fence shorter than the opening one does not close it.
    assert_eq!(check("````\ncode\n```\n").len(), 1);

    let found = check("# Page\n\nsee [x](missing.md)\n");
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].contains(":3: link `missing.md`"), "{found:?}");

    let found = check("# Page\n\n[x](other.md#a-section) [y](#nowhere)\n");
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(found[0].contains("`other.md#a-section`") && found[0].contains("no heading"));
    assert!(found[1].contains("`#nowhere`"), "{found:?}");
}
