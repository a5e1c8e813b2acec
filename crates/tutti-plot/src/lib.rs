//! What tutti's pictures share (the UAV demo's figures, the benchmarks' plots): they are drawn
//! with plotters as SVG, then rasterised to PNG by resvg with the same font (plotters' own
//! bitmap text places glyphs unevenly). Text is measured and drawn with a TrueType font loaded
//! at run time (DejaVu Sans from Debian's fonts-dejavu-core, or the file in `TUTTI_FONT`), so
//! no fontconfig development package is needed to build.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::style::FontStyle;

/// Where the font is looked for, in order (after `TUTTI_FONT`).
pub const FONT_CANDIDATES: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
];

/// Why a picture could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("no TrueType font found: install Debian's fonts-dejavu-core, or set TUTTI_FONT to a .ttf file")]
    NoFont,
    #[error("{what} {path}: {source}")]
    Io { what: &'static str, path: PathBuf, source: std::io::Error },
    #[error("reading the drawn SVG: {0}")]
    Svg(#[from] resvg::usvg::Error),
    #[error("an empty or too large picture")]
    Size,
    /// resvg's PNG encoder's error (its crate, `png`, is not re-exported).
    #[error("writing {path}: {source}")]
    Png { path: PathBuf, source: Box<dyn std::error::Error + Send + Sync> },
}

/// The font registered, or None when none was found.
static FONT: OnceLock<Option<PathBuf>> = OnceLock::new();

/// Registers the sans-serif font once (for plotters' text measurement); returns its file.
pub fn font() -> Result<PathBuf, PlotError> {
    let r = FONT.get_or_init(|| {
        let mut candidates: Vec<PathBuf> = std::env::var_os("TUTTI_FONT").map(PathBuf::from).into_iter().collect();
        candidates.extend(FONT_CANDIDATES.iter().map(PathBuf::from));
        for path in candidates {
            let Ok(bytes) = std::fs::read(&path) else { continue };
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                let _ = plotters::style::register_font("sans-serif", FontStyle::Bold, bytes);
                return Some(path);
            }
        }
        None
    });
    r.clone().ok_or(PlotError::NoFont)
}

/// Writes `svg` to `path` with the extension `.svg`, and its rasterisation to `path` (PNG),
/// text in the font of `font_file`.
pub fn write_svg_and_png(svg: &str, path: &Path, font_file: &Path) -> Result<(), PlotError> {
    let svg_path = path.with_extension("svg");
    std::fs::write(&svg_path, svg).map_err(|source| PlotError::Io { what: "writing", path: svg_path, source })?;
    let mut opt = resvg::usvg::Options::default();
    let db = opt.fontdb_mut();
    let font = std::fs::read(font_file).map_err(|source| PlotError::Io {
        what: "reading",
        path: font_file.to_path_buf(),
        source,
    })?;
    db.load_font_data(font);
    let family = db.faces().next().and_then(|f| f.families.first()).map(|f| f.0.clone());
    if let Some(family) = family {
        db.set_sans_serif_family(family);
    }
    let tree = resvg::usvg::Tree::from_str(svg, &opt)?;
    let size = tree.size().to_int_size();
    let mut pixmap = resvg::tiny_skia::Pixmap::new(size.width(), size.height()).ok_or(PlotError::Size)?;
    pixmap.fill(resvg::tiny_skia::Color::WHITE);
    resvg::render(&tree, resvg::tiny_skia::Transform::default(), &mut pixmap.as_mut());
    pixmap.save_png(path).map_err(|e| PlotError::Png { path: path.to_path_buf(), source: Box::new(e) })
}
