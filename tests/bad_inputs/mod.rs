//! Hostile and careless inputs, table-driven: every case of `cases.toml` runs the `armcomp`
//! binary in a scratch folder of its own and checks the exit code, a fragment of the message
//! (file, line or row, field), that it neither panicked nor hung, and that the files it must
//! not touch kept their content. Every failing case is reported at once.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde::Deserialize;

use crate::common::root;

/// A file of a case's scratch folder.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSpec {
    /// Start from this file: a base file beside `cases.toml`, or a path from the repository
    /// root when it contains a `/`.
    from: Option<String>,
    /// Or from this text.
    text: Option<String>,
    /// `[from, to]` replacements, each of which must apply.
    #[serde(default)]
    replace: Vec<[String; 2]>,
    /// Text added at the end.
    #[serde(default)]
    append: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Case {
    /// What is wrong (or, for a success, what legitimate input it is).
    name: String,
    /// The command line after `armcomp`; `{dir}` is the scratch folder.
    run: Vec<String>,
    /// Expected exit code.
    code: i32,
    /// Fragments the output (stdout and stderr) must contain; `{dir}` is the scratch folder.
    says: Vec<String>,
    /// Fragments the output must not contain (a misleading hint).
    #[serde(default)]
    lacks: Vec<String>,
    /// Files written into the scratch folder first; `{dir}` in their text is the folder.
    #[serde(default)]
    files: BTreeMap<String, FileSpec>,
    /// Then these steps: `["symlink", LINK, TARGET]`, `["fifo", NAME]`, `["readonly", NAME]`,
    /// `["mkdir", NAME]`, `["pad", NAME, BYTES]` (comment lines appended),
    /// `["bytes", NAME, HEX]` (raw bytes appended), `["bom", NAME]` (a UTF-8 byte-order mark
    /// prepended), `["columns", NAME, COUNT]` (columns `extra1`, ... added to the header),
    /// `["rows", NAME, COUNT]` (the last row repeated COUNT more times).
    #[serde(default)]
    setup: Vec<Vec<String>>,
    /// Files that must keep their content (and kind) through the run.
    #[serde(default)]
    unchanged: Vec<String>,
    /// Files that must not exist after the run.
    #[serde(default)]
    absent: Vec<String>,
    /// The user config for the run (`ARMCOMP_CONFIG`).
    config: Option<String>,
    /// Most seconds the run may take: for inputs whose error must come before any work
    /// worth the name (a size far over its limit, a header of many columns).
    seconds: Option<u64>,
}

#[derive(Deserialize)]
struct Table {
    case: Vec<Case>,
}

fn here() -> PathBuf {
    root().join("tests/bad_inputs")
}

/// The text of a file spec, `{dir}` replaced.
fn file_text(spec: &FileSpec, dir: &Path) -> Result<String, String> {
    let mut text = match (&spec.from, &spec.text) {
        (Some(from), None) => {
            let path = if from.contains('/') {
                root().join(from)
            } else {
                here().join(from)
            };
            std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?
        }
        (None, Some(text)) => text.clone(),
        _ => return Err("a file needs exactly one of `from` and `text`".into()),
    };
    for [from, to] in &spec.replace {
        if !text.contains(from.as_str()) {
            return Err(format!("`{from}` is not in the file"));
        }
        text = text.replacen(from.as_str(), to, 1);
    }
    text.push_str(&spec.append);
    Ok(text.replace("{dir}", &dir.display().to_string()))
}

fn setup(step: &[String], dir: &Path) -> Result<(), String> {
    let p = |s: &String| dir.join(s);
    let io = |e: std::io::Error| format!("{step:?}: {e}");
    match step {
        [what, link, target] if what == "symlink" => std::os::unix::fs::symlink(target, p(link)).map_err(io),
        [what, name] if what == "mkdir" => std::fs::create_dir_all(p(name)).map_err(io),
        [what, name] if what == "fifo" => {
            let status = Command::new("mkfifo").arg(p(name)).status().map_err(io)?;
            status
                .success()
                .then_some(())
                .ok_or_else(|| format!("{step:?}: mkfifo failed"))
        }
        [what, name, bytes] if what == "pad" => {
            // Comment lines (TOML and CSV alike) up to the given size.
            let n: usize = bytes.parse().map_err(|_| format!("{step:?}: not a size"))?;
            let line = "# padding to make the file large\n";
            let mut text = std::fs::read_to_string(p(name)).map_err(io)?;
            text.push_str(&line.repeat(n / line.len() + 1));
            std::fs::write(p(name), text).map_err(io)
        }
        [what, name, hex] if what == "bytes" => {
            let mut bytes = std::fs::read(p(name)).map_err(io)?;
            for k in (0..hex.len()).step_by(2) {
                bytes.push(u8::from_str_radix(&hex[k..k + 2], 16).map_err(|_| format!("{step:?}: not hex"))?);
            }
            std::fs::write(p(name), bytes).map_err(io)
        }
        [what, name] if what == "bom" => {
            let mut bytes = vec![0xef, 0xbb, 0xbf];
            bytes.extend(std::fs::read(p(name)).map_err(io)?);
            std::fs::write(p(name), bytes).map_err(io)
        }
        [what, name, count] if what == "columns" => {
            let n: usize = count.parse().map_err(|_| format!("{step:?}: not a count"))?;
            let text = std::fs::read_to_string(p(name)).map_err(io)?;
            let (header, rest) = text.split_once('\n').unwrap_or((&text, ""));
            let extra: String = (1..=n).map(|k| format!(",extra{k}")).collect();
            std::fs::write(p(name), format!("{header}{extra}\n{rest}")).map_err(io)
        }
        [what, name, count] if what == "rows" => {
            let n: usize = count.parse().map_err(|_| format!("{step:?}: not a count"))?;
            let text = std::fs::read_to_string(p(name)).map_err(io)?;
            let last = text.lines().last().unwrap_or_default();
            std::fs::write(p(name), text.clone() + &format!("{last}\n").repeat(n)).map_err(io)
        }
        [what, name] if what == "readonly" => {
            let mut perms = std::fs::metadata(p(name)).map_err(io)?.permissions();
            perms.set_readonly(true);
            std::fs::set_permissions(p(name), perms).map_err(io)
        }
        _ => Err(format!("unknown setup step {step:?}")),
    }
}

/// What a file is: its kind and, for a regular file, its content.
fn snapshot(path: &Path) -> String {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => format!("link to {:?}", std::fs::read_link(path).ok()),
        Ok(m) if m.is_file() => format!("file {:?}", std::fs::read(path).ok()),
        Ok(m) => format!("{:?}", m.file_type()),
        Err(_) => "absent".into(),
    }
}

/// Longest a case may run: every case fails or succeeds on small files, so this is a hang.
const HANG: Duration = Duration::from_secs(60);

/// Runs one case; `Err` says everything that went wrong.
fn run_case(case: &Case) -> Result<(), String> {
    let scratch = tempfile::Builder::new()
        .prefix("armcomp-bad-input")
        .tempdir()
        .map_err(|e| e.to_string())?;
    let dir = scratch.path();
    for (name, spec) in &case.files {
        let text = file_text(spec, dir).map_err(|e| format!("{name}: {e}"))?;
        let path = dir.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| format!("{name}: {e}"))?;
        }
        std::fs::write(path, text).map_err(|e| format!("{name}: {e}"))?;
    }
    for step in &case.setup {
        setup(step, dir)?;
    }
    let before: Vec<String> = case.unchanged.iter().map(|f| snapshot(&dir.join(f))).collect();
    let subst = |s: &String| s.replace("{dir}", &dir.display().to_string());
    let mut command = Command::new(env!("CARGO_BIN_EXE_armcomp"));
    command
        .args(case.run.iter().map(subst))
        .current_dir(dir)
        .env_remove("ARMCOMP_CONFIG")
        .env("XDG_CONFIG_HOME", dir.join("no-config"))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if let Some(config) = &case.config {
        let path = dir.join("config.toml");
        std::fs::write(&path, subst(config)).map_err(|e| e.to_string())?;
        command.env("ARMCOMP_CONFIG", path);
    }
    let mut child = command.spawn().map_err(|e| e.to_string())?;
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            break status;
        }
        if started.elapsed() > HANG {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("still running after {HANG:?}: a hang"));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let took = started.elapsed();
    let out = child.wait_with_output().map_err(|e| e.to_string())?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let mut wrong = Vec::new();
    if status.code() != Some(case.code) {
        wrong.push(format!("exit code {:?}, expected {}", status.code(), case.code));
    }
    if let Some(most) = case.seconds
        && took > Duration::from_secs(most)
    {
        wrong.push(format!("took {took:?}, more than {most} s"));
    }
    if text.contains("panicked") {
        wrong.push("panicked".into());
    }
    for s in &case.says {
        if !text.contains(&subst(s)) {
            wrong.push(format!("does not say `{}`", subst(s)));
        }
    }
    for s in &case.lacks {
        if text.contains(&subst(s)) {
            wrong.push(format!("says `{}`", subst(s)));
        }
    }
    for (f, was) in case.unchanged.iter().zip(&before) {
        if snapshot(&dir.join(f)) != *was {
            wrong.push(format!("`{f}` changed"));
        }
    }
    for f in &case.absent {
        if std::fs::symlink_metadata(dir.join(f)).is_ok() {
            wrong.push(format!("`{f}` exists"));
        }
    }
    // Outputs go through temporaries named after them; none may be left behind.
    let leftovers: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| e.to_string())?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    if !leftovers.is_empty() {
        wrong.push(format!("left {leftovers:?}"));
    }
    if wrong.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{}\n    output: {}",
            wrong.join("; "),
            text.trim_end().replace('\n', "\n            ")
        ))
    }
}

#[test]
fn every_bad_input_gets_its_clear_error_and_loses_nothing() {
    let text = std::fs::read_to_string(here().join("cases.toml")).unwrap();
    let table: Table = toml::from_str(&text).unwrap();
    assert!(table.case.len() >= 60, "the suite holds {} cases", table.case.len());
    let mut names = std::collections::HashSet::new();
    let failures: Vec<String> = table
        .case
        .iter()
        .filter_map(|case| {
            let duplicate = (!names.insert(case.name.as_str())).then(|| "duplicate case name".to_string());
            let result = duplicate.map_or_else(|| run_case(case), Err);
            result.err().map(|e| format!("{}: {e}", case.name))
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        table.case.len(),
        failures.join("\n")
    );
}
