//! The library's error type: every failure a user can cause, with where it happened.

use std::path::PathBuf;

/// A position in a scene file, 1-based.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    pub line: usize,
    pub column: usize,
}

impl Location {
    /// The line and column of byte `offset` in `text`.
    pub fn of_offset(text: &str, offset: usize) -> Self {
        let offset = offset.min(text.len());
        let before = &text[..offset];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before[line_start..].chars().count() + 1;
        Self { line, column }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene file is not valid TOML or does not have the scene's shape.
    #[error("{path}:{line}:{column}: {message}", path = path.display(), line = at.line, column = at.column)]
    SceneSyntax {
        path: PathBuf,
        at: Location,
        message: String,
    },
    /// A value in the scene file is well-formed but not acceptable.
    #[error("{path}:{line}:{column}: field `{field}`: {message}", path = path.display(), line = at.line, column = at.column)]
    SceneValue {
        path: PathBuf,
        at: Location,
        field: String,
        message: String,
    },
    /// A setting given on the command line (or otherwise outside a file) is not acceptable.
    #[error("invalid setting `{field}`: {message}")]
    Setting { field: String, message: String },
    #[error("{path}: {cause}", path = path.display())]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    #[error("{path}: {message}", path = path.display())]
    Image { path: PathBuf, message: String },
    /// Parts that do not add up to an image.
    #[error("cannot merge: {0}")]
    Merge(String),
    /// A partial render or checkpoint that cannot be used.
    #[error("{path}: {message}", path = path.display())]
    Partial { path: PathBuf, message: String },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_are_one_based() {
        let text = "a = 1\nbb = 2\n";
        assert_eq!(
            Location::of_offset(text, 0),
            Location { line: 1, column: 1 }
        );
        assert_eq!(
            Location::of_offset(text, 6),
            Location { line: 2, column: 1 }
        );
        assert_eq!(
            Location::of_offset(text, 9),
            Location { line: 2, column: 4 }
        );
    }
}
