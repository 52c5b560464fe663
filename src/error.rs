//! The library's usage error: a request that cannot be carried out as given (exit code 2
//! in the CLI), as opposed to a fault met while running.

/// A usage or configuration error (the CLI exits 2 on it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}
