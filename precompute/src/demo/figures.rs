//! Figures of the report: images (linear EXR and tonemapped sRGB PNG), labelled image grids
//! (paper Figs. 1 and 9), false-colour pdf grids (Fig. 7) and log-log convergence plots
//! (Fig. 8).
//!
//! Text is drawn by plotters with an embedded font (`fixtures/fonts/`, Roboto, Apache-2.0), so
//! the figures render the same on a machine without any system fonts. Every file is written
//! atomically ([`crate::util::io::atomic_write`]).

use std::path::Path;
use std::sync::Once;

use anyhow::{anyhow, Result};
use image::ImageEncoder;
use plotters::prelude::*;
use plotters::style::FontStyle;

use neusample_render::{luminance, Image};

use crate::util::io;

/// The embedded plot font (a subset of Roboto Regular; licence beside the file).
static FONT_BYTES: &[u8] = include_bytes!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../fixtures/fonts/Roboto-Regular-subset.ttf"
));

/// The font family name plotters knows the embedded font by.
pub const FONT: &str = "sans-serif";

/// Registers the embedded font with plotters (once per process).
pub fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is a committed file checked by the tests; a failure leaves text undrawn.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
    });
}

fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("drawing failed: {e:?}")
}

// ---------------------------------------------------------------------------------------
// Tonemapping and encoding
// ---------------------------------------------------------------------------------------

/// An 8-bit sRGB image.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb8 {
    /// Width.
    pub width: usize,
    /// Height.
    pub height: usize,
    /// `3 · width · height` bytes, row-major.
    pub data: Vec<u8>,
}

impl Rgb8 {
    /// A solid image.
    #[must_use]
    pub fn filled(width: usize, height: usize, rgb: [u8; 3]) -> Rgb8 {
        let mut data = Vec::with_capacity(3 * width * height);
        for _ in 0..width * height {
            data.extend_from_slice(&rgb);
        }
        Rgb8 {
            width,
            height,
            data,
        }
    }

    /// Nearest-neighbour enlargement by an integer factor.
    #[must_use]
    pub fn upscale(&self, k: usize) -> Rgb8 {
        let k = k.max(1);
        let (w, h) = (self.width * k, self.height * k);
        let mut data = Vec::with_capacity(3 * w * h);
        for y in 0..h {
            for x in 0..w {
                let i = 3 * ((y / k) * self.width + x / k);
                data.extend_from_slice(&self.data[i..i + 3]);
            }
        }
        Rgb8 {
            width: w,
            height: h,
            data,
        }
    }

    /// Copies `src` with its top-left corner at `(x0, y0)` (clipped).
    pub fn blit(&mut self, src: &Rgb8, x0: usize, y0: usize) {
        for y in 0..src.height {
            let ty = y0 + y;
            if ty >= self.height {
                break;
            }
            let n = src.width.min(self.width.saturating_sub(x0));
            let d = 3 * (ty * self.width + x0);
            let s = 3 * (y * src.width);
            self.data[d..d + 3 * n].copy_from_slice(&src.data[s..s + 3 * n]);
        }
    }
}

/// The sRGB transfer function of a linear value in `[0, 1]`.
#[must_use]
pub fn srgb_encode(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// ACES filmic curve (Narkowicz 2015 fit).
#[must_use]
pub fn aces(x: f32) -> f32 {
    let x = x.max(0.0);
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// An exposure that maps the mean luminance of the masked pixels of `img` to 0.35 (a
/// mid-grey key); 1 when there is nothing to measure.
#[must_use]
pub fn auto_exposure(img: &Image, mask: &[bool]) -> f32 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for (i, c) in img.data.iter().enumerate() {
        if mask.get(i).copied().unwrap_or(true) {
            let y = f64::from(luminance(*c));
            if y.is_finite() {
                s += y;
                n += 1;
            }
        }
    }
    let mean = if n > 0 { s / n as f64 } else { 0.0 };
    if mean > 0.0 {
        (0.35 / mean) as f32
    } else {
        1.0
    }
}

/// Tonemaps a linear image: exposure, ACES filmic, sRGB.
#[must_use]
pub fn tonemap(img: &Image, exposure: f32) -> Rgb8 {
    let mut data = Vec::with_capacity(3 * img.data.len());
    for c in &img.data {
        for v in c {
            let v = if v.is_finite() { *v } else { 0.0 };
            data.push((srgb_encode(aces(v * exposure)) * 255.0 + 0.5) as u8);
        }
    }
    Rgb8 {
        width: img.width,
        height: img.height,
        data,
    }
}

/// PNG bytes of an sRGB image.
pub fn png_bytes(img: &Rgb8) -> Result<Vec<u8>> {
    let mut buf = Vec::new();
    image::codecs::png::PngEncoder::new(&mut buf).write_image(
        &img.data,
        img.width as u32,
        img.height as u32,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(buf)
}

/// Writes a PNG atomically.
pub fn write_png(path: &Path, img: &Rgb8) -> Result<()> {
    io::atomic_write(path, &png_bytes(img)?)
}

/// OpenEXR bytes (RGB, f32, lossless) of a linear image.
pub fn exr_bytes(img: &Image) -> Result<Vec<u8>> {
    use exr::prelude::*;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let c = img.at(x, y);
        (c[0], c[1], c[2])
    });
    let image = exr::image::Image::from_channels((img.width, img.height), channels);
    let mut cursor = std::io::Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut cursor)
        .map_err(|e| anyhow!("EXR encoding failed: {e}"))?;
    Ok(cursor.into_inner())
}

/// Writes an EXR atomically.
pub fn write_exr(path: &Path, img: &Image) -> Result<()> {
    io::atomic_write(path, &exr_bytes(img)?)
}

// ---------------------------------------------------------------------------------------
// Text and grids
// ---------------------------------------------------------------------------------------

/// Draws `lines` of text onto `img` at pixel positions, in the embedded font.
pub fn draw_text(img: &mut Rgb8, items: &[(String, (i32, i32), u32, RGBColor)]) -> Result<()> {
    register_font();
    {
        let root = BitMapBackend::with_buffer(&mut img.data, (img.width as u32, img.height as u32))
            .into_drawing_area();
        for (text, pos, size, color) in items {
            let style = TextStyle::from((FONT, *size as f64).into_font()).color(color);
            root.draw_text(text, &style, *pos).map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    Ok(())
}

/// Tiles narrower than this are enlarged in [`labelled_grid`].
pub const MIN_TILE_WIDTH: usize = 150;

/// A labelled grid of equally sized tiles (Fig. 1/9 style): `cols` columns, each tile with a
/// caption of up to two lines underneath, and an optional title on top.
pub fn labelled_grid(tiles: &[(Rgb8, [String; 2])], cols: usize, title: &str) -> Result<Rgb8> {
    let cols = cols.max(1);
    // Small tiles are enlarged (nearest neighbour) so that their captions fit under them.
    let k = tiles
        .first()
        .map_or(1, |(t, _)| MIN_TILE_WIDTH.div_ceil(t.width.max(1)));
    let (tw, th) = tiles
        .first()
        .map_or((1, 1), |(t, _)| (t.width * k, t.height * k));
    let rows = tiles.len().div_ceil(cols);
    let pad = 6;
    let caption = 34;
    let head = if title.is_empty() { 0 } else { 26 };
    let w = (cols * (tw + pad) + pad).max(title.chars().count() * 7 + 2 * pad);
    let h = head + rows * (th + caption + pad) + pad;
    let mut out = Rgb8::filled(w, h, [255, 255, 255]);
    let mut texts = Vec::new();
    if !title.is_empty() {
        texts.push((title.to_string(), (pad as i32, 5), 16, BLACK));
    }
    for (i, (tile, cap)) in tiles.iter().enumerate() {
        let (c, r) = (i % cols, i / cols);
        let x = pad + c * (tw + pad);
        let y = head + pad + r * (th + caption + pad);
        if k > 1 {
            out.blit(&tile.upscale(k), x, y);
        } else {
            out.blit(tile, x, y);
        }
        texts.push((
            cap[0].clone(),
            (x as i32 + 2, (y + th + 3) as i32),
            14,
            BLACK,
        ));
        texts.push((
            cap[1].clone(),
            (x as i32 + 2, (y + th + 18) as i32),
            12,
            RGBColor(70, 70, 70),
        ));
    }
    draw_text(&mut out, &texts)?;
    Ok(out)
}

/// The viridis colour map at `t ∈ [0, 1]` (piecewise-linear through 9 anchors).
#[must_use]
pub fn viridis(t: f32) -> [u8; 3] {
    const A: [[f32; 3]; 9] = [
        [68.0, 1.0, 84.0],
        [71.0, 44.0, 122.0],
        [59.0, 81.0, 139.0],
        [44.0, 113.0, 142.0],
        [33.0, 144.0, 141.0],
        [39.0, 173.0, 129.0],
        [92.0, 200.0, 99.0],
        [170.0, 220.0, 50.0],
        [253.0, 231.0, 37.0],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * 8.0;
    let i = (x as usize).min(7);
    let f = x - i as f32;
    let mut c = [0u8; 3];
    for k in 0..3 {
        c[k] = (A[i][k] + (A[i + 1][k] - A[i][k]) * f + 0.5) as u8;
    }
    c
}

/// A false-colour image of a density on the projected disk: `size × size` pixels over
/// `[−1, 1]²` (y up), colour `viridis(√(p / vmax))`, grey outside the disk.
pub fn disk_image(size: usize, vmax: f32, pdf: impl Fn(glam::Vec2) -> f32) -> Rgb8 {
    let mut img = Rgb8::filled(size, size, [40, 40, 40]);
    for y in 0..size {
        for x in 0..size {
            let p = glam::Vec2::new(
                -1.0 + 2.0 * (x as f32 + 0.5) / size as f32,
                1.0 - 2.0 * (y as f32 + 0.5) / size as f32,
            );
            if p.length_squared() >= 1.0 {
                continue;
            }
            let v = pdf(p);
            let t = if vmax > 0.0 {
                (v / vmax).max(0.0).sqrt()
            } else {
                0.0
            };
            let c = viridis(t);
            let i = 3 * (y * size + x);
            img.data[i..i + 3].copy_from_slice(&c);
        }
    }
    img
}

// ---------------------------------------------------------------------------------------
// Plots
// ---------------------------------------------------------------------------------------

/// One line of a plot.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// Points `(x, y)`; non-positive or non-finite values are skipped (log axes).
    pub points: Vec<(f64, f64)>,
}

fn log_range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals {
        if v > 0.0 && v.is_finite() {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return (1e-3, 1.0);
    }
    if hi <= lo {
        hi = lo * 10.0;
    }
    (lo / 1.5, hi * 1.5)
}

/// Log-log convergence plots side by side (Fig. 8): MSE vs samples per pixel and MSE vs
/// time. `by_spp` and `by_time` hold one series per method.
pub fn convergence_plot(
    title: &str,
    by_spp: &[Series],
    by_time: &[Series],
    time_label: &str,
) -> Result<Rgb8> {
    register_font();
    let (w, h) = (1100usize, 460usize);
    let mut out = Rgb8::filled(w, h, [255, 255, 255]);
    {
        let root =
            BitMapBackend::with_buffer(&mut out.data, (w as u32, h as u32)).into_drawing_area();
        let root = root
            .titled(title, (FONT, 20).into_font())
            .map_err(plot_err)?;
        let (left, right) = root.split_horizontally(w as u32 / 2);
        for (area, series, xlabel, caption) in [
            (
                &left,
                by_spp,
                "samples per pixel",
                "MSE vs spp (equal samples)",
            ),
            (&right, by_time, time_label, "MSE vs time (equal time)"),
        ] {
            let (x0, x1) = log_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
            let (y0, y1) = log_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
            let mut chart = ChartBuilder::on(area)
                .caption(caption, (FONT, 16).into_font())
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
                .map_err(plot_err)?;
            chart
                .configure_mesh()
                .x_desc(xlabel)
                .y_desc("MSE")
                .label_style((FONT, 13).into_font())
                .light_line_style(RGBColor(238, 238, 238))
                .max_light_lines(3)
                .y_label_formatter(&|v| format!("{v:.0e}"))
                .x_label_formatter(&|v| {
                    if *v >= 1.0 {
                        format!("{v:.0}")
                    } else {
                        format!("{v:.2}")
                    }
                })
                .draw()
                .map_err(plot_err)?;
            for (i, s) in series.iter().enumerate() {
                let color = Palette99::pick(i).to_rgba();
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite())
                    .collect();
                chart
                    .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                    .map_err(plot_err)?
                    .label(s.name.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                    });
                chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                    .map_err(plot_err)?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .label_font((FONT, 12).into_font())
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    Ok(out)
}
