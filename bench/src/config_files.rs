//! Configurations the benches derive from a base file: parsed as a TOML table, edited
//! (a fault, a gate, a layout), and written to a temporary directory that is removed when
//! the bench ends. Relative paths of the base (its `layout`) are made absolute first, so
//! the derived file means the same wherever it is written.

use std::path::{Path, PathBuf};

use anyhow::Context;

/// A temporary directory for derived files, removed on drop.
pub struct BenchDir {
    dir: PathBuf,
}

impl BenchDir {
    /// A fresh directory for bench `name`.
    pub fn new(name: &str) -> anyhow::Result<Self> {
        let dir = std::env::temp_dir().join(format!("gelgrip-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Self { dir })
    }

    /// Write `table` as `file` in the directory; returns its path.
    pub fn write(&self, file: &str, table: &toml::Table) -> anyhow::Result<PathBuf> {
        let path = self.dir.join(file);
        std::fs::write(&path, toml::to_string(table)?)
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(path)
    }
}

impl Drop for BenchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The TOML file `path` as a table.
pub fn load(path: &Path) -> anyhow::Result<toml::Table> {
    let text = std::fs::read_to_string(path).with_context(|| {
        format!(
            "reading {} (run the bench from the repository)",
            path.display()
        )
    })?;
    text.parse()
        .with_context(|| format!("parsing {}", path.display()))
}

/// The configuration `path` with its `layout` made absolute.
pub fn load_config(path: &Path) -> anyhow::Result<toml::Table> {
    let mut table = load(path)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    if let Some(toml::Value::String(layout)) = table.get("layout") {
        let abs = std::fs::canonicalize(dir.join(layout))
            .with_context(|| format!("the layout {layout} of {}", path.display()))?;
        table.insert("layout".into(), abs.display().to_string().into());
    }
    Ok(table)
}

/// The sub-table `key` of `table`, created when missing.
pub fn section<'a>(table: &'a mut toml::Table, key: &str) -> anyhow::Result<&'a mut toml::Table> {
    let value = table
        .entry(key)
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    value
        .as_table_mut()
        .with_context(|| format!("`{key}` is not a table"))
}

/// The scene files: those given, else every `.toml` of `configs/scenes`.
pub fn scene_files(given: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    if !given.is_empty() {
        return Ok(given.to_vec());
    }
    let dir = Path::new("configs/scenes");
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| {
            format!(
                "listing {} (run from the repository, or pass --scene)",
                dir.display()
            )
        })?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    out.sort();
    Ok(out)
}
