//! The error returned for an invalid game configuration.

/// A configuration that cannot be parsed or is out of range.
///
/// Every message names the offending key, e.g. "unknown key `widht` in config"
/// or "`width` = 31 is out of range: must be 32..=160".
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// A key that the schema does not know.
    #[error("unknown key `{key}` in config{}", at_path(.path))]
    UnknownKey {
        /// The unknown key.
        key: String,
        /// Where it was found (dotted path of the containing object, empty at the top).
        path: String,
    },
    /// The JSON could not be parsed into the schema (syntax error, wrong type, missing key).
    #[error("invalid config{}: {message}", at_path(.path))]
    Parse {
        /// Dotted path of the value that failed (may be empty).
        path: String,
        /// What went wrong.
        message: String,
    },
    /// A value that parses but is not allowed.
    #[error("`{key}` = {value} {}", phrase(.reason))]
    Invalid {
        /// Dotted key, e.g. `dungeon.maze_rate_inv`.
        key: String,
        /// The offending value, as written in JSON.
        value: String,
        /// Why it is invalid.
        reason: String,
    },
    /// A feature of the original that this engine does not implement.
    #[error("`{key}` = {value} is not supported: {reason}")]
    Unsupported {
        /// Dotted key.
        key: String,
        /// The value.
        value: String,
        /// Explanation.
        reason: String,
    },
}

/// "must be ..." and "is ..." reasons read on directly; others follow "is invalid:".
fn phrase(reason: &str) -> String {
    if reason.starts_with("must") || reason.starts_with("is ") {
        reason.to_string()
    } else {
        format!("is invalid: {reason}")
    }
}

fn at_path(path: &str) -> String {
    if path.is_empty() || path == "." {
        String::new()
    } else {
        format!(" at `{path}`")
    }
}

impl ConfigError {
    /// Shorthand for [`ConfigError::Invalid`].
    pub(crate) fn invalid(
        key: &str,
        value: impl std::fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        ConfigError::Invalid {
            key: key.to_string(),
            value: value.to_string(),
            reason: reason.into(),
        }
    }

    /// Converts a serde error (with its path) into a `ConfigError`.
    pub(crate) fn from_serde(err: serde_path_to_error::Error<serde_json::Error>) -> Self {
        let path = err.path().to_string();
        let inner = err.into_inner();
        let msg = inner.to_string();
        if let Some(rest) = msg.strip_prefix("unknown field `")
            && let Some(end) = rest.find('`')
        {
            let key = rest[..end].to_string();
            // serde_path_to_error's path ends with the unknown key itself.
            let parent = match path.rfind('.') {
                Some(i) => path[..i].to_string(),
                None => String::new(),
            };
            return ConfigError::UnknownKey { key, path: parent };
        }
        ConfigError::Parse { path, message: msg }
    }
}
