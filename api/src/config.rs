//! The user config: the plugin folders the user trusts and how large inputs may be.
//!
//! It is `$ARMCOMP_CONFIG` when set, else `armcomp/config.toml` in `$XDG_CONFIG_HOME` (or
//! `~/.config`); a missing file is an empty config:
//!
//! ```toml
//! plugin_dirs = ["/opt/armcomp/plugins"]   # libraries here load without --allow-plugins
//! max_input_mb = 1024                      # largest input file (default 256)
//! ```

use std::path::{Path, PathBuf};

use armcomp_core::Result;
use armcomp_core::robot::robot_file::SourceFile;
use armcomp_core::support::io::InputLimits;
use serde::Deserialize;

/// What the user config says.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UserConfig {
    /// Folders whose plugin libraries any robot file may load (relative to the config's folder).
    #[serde(default)]
    pub plugin_dirs: Vec<PathBuf>,
    /// The largest input file armcomp reads, in MiB.
    #[serde(default)]
    pub max_input_mb: Option<u64>,
}

impl UserConfig {
    /// The input limits it sets, for the readers of the run.
    pub fn input_limits(&self) -> InputLimits {
        self.max_input_mb
            .map_or_else(InputLimits::default, InputLimits::from_mib)
    }
}

/// Reads the user config, makes its trusted plugin folders the process's plugin policy with
/// `allow_plugins` as the user's permission to load the libraries robot files name, and
/// returns the input limits the caller passes to its readers.
pub fn apply(allow_plugins: bool) -> Result<InputLimits> {
    let config = load()?;
    let limits = config.input_limits();
    armcomp_sdk::set_policy(armcomp_sdk::PluginPolicy {
        allow: allow_plugins,
        trusted_dirs: config.plugin_dirs,
    });
    Ok(limits)
}

/// Where the user config is looked for, if anywhere.
pub fn config_path() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("ARMCOMP_CONFIG") {
        return Some(PathBuf::from(p));
    }
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".config")))?;
    Some(base.join("armcomp").join("config.toml"))
}

/// Reads the user config at `path`; an absent file is the empty config unless `required`.
/// Errors name the file, line and field.
pub fn read(path: &Path, required: bool) -> Result<UserConfig> {
    if !required && std::fs::symlink_metadata(path).is_err() {
        return Ok(UserConfig::default());
    }
    let src = SourceFile::read(path, InputLimits::default())?;
    let mut config: UserConfig = src.parse()?;
    let dir = path.parent().unwrap_or(Path::new("."));
    for d in &mut config.plugin_dirs {
        if d.is_relative() {
            *d = dir.join(&*d);
        }
    }
    if config.max_input_mb == Some(0) {
        return Err(src.invalid(vec![armcomp_core::Issue::new(
            "max_input_mb",
            "expected a size of at least 1 (MiB)",
        )]));
    }
    Ok(config)
}

/// Reads the user config from where [`config_path`] says (required when `$ARMCOMP_CONFIG`
/// names it).
pub fn load() -> Result<UserConfig> {
    match config_path() {
        Some(p) => read(&p, std::env::var_os("ARMCOMP_CONFIG").is_some()),
        None => Ok(UserConfig::default()),
    }
}
