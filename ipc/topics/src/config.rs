//! One TOML file configures the whole stack; each process reads its own sections from it.
//! Every key has a default, so no file at all is a valid configuration. Unknown keys are errors
//! (a typo must not silently fall back to a default); errors name the file, section and key.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;

/// Why a configuration could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read or is not valid TOML.
    #[error(transparent)]
    File(#[from] mtanet_summaries::files::FileError),
    /// A section has a wrong, unknown or badly typed key.
    #[error("config file {path}, section [{section}]: {message}")]
    Section {
        path: PathBuf,
        section: String,
        message: String,
    },
    /// A value is out of range (checked after parsing).
    #[error("config file {path}: {key} {message}")]
    Invalid {
        path: PathBuf,
        key: String,
        message: String,
    },
}

/// The top-level sections a stack config may have.
pub const SECTIONS: [&str; 5] = ["ipc", "simulator", "predictor", "trainer", "stack"];

/// A parsed config file (or the empty one when no file was given).
#[derive(Debug, Clone, Default)]
pub struct ConfigFile {
    path: Option<PathBuf>,
    table: toml::Table,
}

impl ConfigFile {
    pub fn load(path: Option<&Path>) -> Result<Self, ConfigError> {
        match path {
            None => Ok(Self::default()),
            Some(path) => Self::from_table(mtanet_summaries::files::read_table(path)?, path),
        }
    }

    /// Parses a stack config held in memory (`path` names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        let table = toml::from_str(text).map_err(|e| mtanet_summaries::files::FileError::Toml {
            path: path.into(),
            message: e.to_string(),
        })?;
        Self::from_table(table, path)
    }

    /// A top-level key that is not one of [`SECTIONS`] (a misspelt `[trainr]`, say) is an
    /// error naming it, not silently ignored.
    fn from_table(table: toml::Table, path: &Path) -> Result<Self, ConfigError> {
        if let Some(unknown) = table.keys().find(|k| !SECTIONS.contains(&k.as_str())) {
            return Err(ConfigError::Section {
                path: path.into(),
                section: unknown.clone(),
                message: format!("unknown section, expected one of {}", SECTIONS.join(", ")),
            });
        }
        Ok(Self {
            path: Some(path.into()),
            table,
        })
    }

    /// The file's path for messages ("<defaults>" without a file).
    pub fn origin(&self) -> PathBuf {
        self.path
            .clone()
            .unwrap_or_else(|| PathBuf::from("<defaults>"))
    }

    /// Section `name` (dotted for nested tables, e.g. "simulator.teacher"), defaults where absent.
    pub fn section<T: DeserializeOwned + Default>(&self, name: &str) -> Result<T, ConfigError> {
        let mut table = &self.table;
        for part in name.split('.') {
            match table.get(part) {
                None => return Ok(T::default()),
                Some(toml::Value::Table(t)) => table = t,
                // `trainer = 5` is a mistake to report, not a section to default silently.
                Some(other) => {
                    return Err(ConfigError::Section {
                        path: self.origin(),
                        section: name.into(),
                        message: format!(
                            "`{part}` must be a table ([{part}]), not a value of type {}",
                            other.type_str()
                        ),
                    });
                }
            }
        }
        T::deserialize(toml::Value::Table(table.clone())).map_err(|e| ConfigError::Section {
            path: self.origin(),
            section: name.into(),
            message: e.to_string().trim().to_string(),
        })
    }

    /// An [`ConfigError::Invalid`] for a value that parsed but makes no sense.
    pub fn invalid(&self, key: &str, message: impl Into<String>) -> ConfigError {
        ConfigError::Invalid {
            path: self.origin(),
            key: key.into(),
            message: message.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::IpcConfig;

    #[test]
    fn missing_section_gives_defaults() {
        let f = ConfigFile::parse("[simulator]\nx = 1\n", Path::new("a.toml")).unwrap();
        assert_eq!(f.section::<IpcConfig>("ipc").unwrap(), IpcConfig::default());
    }

    #[test]
    fn unknown_key_is_named_with_file_and_section() {
        let f = ConfigFile::parse("[ipc]\nnamespce = \"x\"\n", Path::new("stack.toml")).unwrap();
        let msg = f.section::<IpcConfig>("ipc").unwrap_err().to_string();
        assert!(
            msg.contains("stack.toml") && msg.contains("[ipc]") && msg.contains("namespce"),
            "{msg}"
        );
    }

    #[test]
    fn a_misspelt_section_is_named_with_the_file() {
        let msg = ConfigFile::parse("[trainr]\nnice = 5\n", Path::new("stack.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("stack.toml")
                && msg.contains("[trainr]")
                && msg.contains("unknown section"),
            "{msg}"
        );
        let wrong_type = ConfigFile::parse("[ipc]\nnamespace = 5\n", Path::new("s.toml")).unwrap();
        let msg = wrong_type
            .section::<IpcConfig>("ipc")
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("s.toml") && msg.contains("[ipc]") && msg.contains("string"),
            "{msg}"
        );
    }

    #[test]
    fn a_section_that_is_not_a_table_is_an_error_not_its_defaults() {
        let f = ConfigFile::parse("ipc = 5\n", Path::new("mine.toml")).unwrap();
        let msg = f.section::<IpcConfig>("ipc").unwrap_err().to_string();
        assert!(
            msg.contains("mine.toml") && msg.contains("[ipc]") && msg.contains("must be a table"),
            "{msg}"
        );
        let f = ConfigFile::parse("[simulator]\nscene = \"x\"\n", Path::new("m.toml")).unwrap();
        let msg = f
            .section::<IpcConfig>("simulator.scene")
            .unwrap_err()
            .to_string();
        assert!(msg.contains("`scene` must be a table"), "{msg}");
    }

    #[test]
    fn bad_toml_is_reported() {
        let msg = ConfigFile::parse("[ipc\n", Path::new("b.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("b.toml") && msg.contains("not valid TOML"),
            "{msg}"
        );
    }
}
