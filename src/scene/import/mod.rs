//! Scenes in other renderers' formats, read into the description a TOML scene file gives
//! ([`super::description::SceneDescription`]): Mitsuba 3 XML and pbrt-v4.
pub(crate) mod mitsuba;
pub(crate) mod pbrt;

/// How foreign scene files are read.
#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// `-D name=value`: values for `$name` in a Mitsuba scene (over its `<default>`s).
    pub defines: Vec<(String, String)>,
    /// Anything outside the supported subset is an error, not a warning.
    pub strict: bool,
}

/// The formats a scene file can be in, by its extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Toml,
    Mitsuba,
    Pbrt,
}

impl Format {
    #[must_use]
    pub fn of(path: &std::path::Path) -> Self {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("xml") => Format::Mitsuba,
            Some("pbrt") => Format::Pbrt,
            _ => Format::Toml,
        }
    }
}
