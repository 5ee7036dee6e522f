//! Per-scene charts of time against error, as SVG and PNG, with plotters.
//!
//! No system font is needed: the SVG names a generic `sans-serif` family for the viewer to
//! draw, and the PNG's text is drawn with the public-domain font8x8 glyphs (the viewer's
//! overlay font) through [`GlyphBitmap`], a bitmap backend whose only change is text.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

pub use self::glyphs::GlyphBitmap;

/// One line of the chart: a method's sweep along one axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub label: String,
    /// Which method (picks the colour): the index in the run's method list.
    pub colour: usize,
    /// (time ms, error), in sweep order.
    pub points: Vec<(f64, f64)>,
    /// What each point stands for along the series' axis (`512` on `map.resolution`), drawn
    /// beside it; empty for a series of one setting.
    pub point_labels: Vec<String>,
}

/// What one chart shows.
#[derive(Clone, Debug, PartialEq)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// The Pareto front, in time order.
    pub front: Vec<(f64, f64)>,
    /// The point `auto` picks under the run's error bound, ringed.
    pub auto: Option<(f64, f64)>,
    /// The reference's own error (pooled over the scene's lights): errors below it cannot be
    /// told apart, drawn as a band along the time axis; 0 (hard lights) draws none.
    pub reference_error: f64,
}

/// The plot's size; the legend goes to its right, as wide as its longest entry.
const SIZE: (u32, u32) = (900, 600);
/// Legend text, in pixels: the PNG's glyphs are 8 pixels a character at this size (the SVG's
/// sans-serif is narrower), so the legend's width follows from its entries' lengths.
const LEGEND_FONT: u32 = 14;
const LEGEND_CHAR: u32 = 8;

/// What the legend shows for an entry.
enum Key {
    Line(RGBColor),
    Front,
    Auto,
    Band,
}

/// `auto`'s ring and the reference's band.
const RING: RGBColor = RGBColor(220, 0, 120);
const BAND: RGBColor = RGBColor(160, 160, 160);

fn colour(i: usize) -> RGBColor {
    const PALETTE: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    PALETTE[i % PALETTE.len()]
}

/// A time tick: whole milliseconds where whole or from 10 up, else three significant digits or
/// so.
fn tick(v: f64) -> String {
    match v {
        v if v >= 10.0 || (v >= 1.0 && v.fract() == 0.0) => format!("{v:.0}"),
        v if v >= 1.0 => format!("{v:.1}"),
        v if v >= 0.1 => format!("{v:.2}"),
        v => format!("{v:.3}"),
    }
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Ticks for a log axis over `lo..hi`: 1, 2 and 5 times the powers of ten inside it; where that
/// leaves fewer than five, 3 too; where still fewer, every whole multiple: an axis that spans
/// less than a decade still reads, and a wide one is not crowded.
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return Vec::new();
    }
    let decades = lo.log10().floor() as i32..=hi.log10().ceil() as i32;
    let with = |steps: &[f64]| -> Vec<f64> {
        decades
            .clone()
            .flat_map(|d| steps.iter().map(move |s| s * 10f64.powi(d)))
            .filter(|&t| t >= lo && t <= hi)
            .collect()
    };
    for steps in [&[1.0, 2.0, 5.0][..], &[1.0, 2.0, 3.0, 5.0]] {
        let ticks = with(steps);
        if ticks.len() >= 5 {
            return ticks;
        }
    }
    with(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
}

impl Chart {
    /// The legend's entries, in order.
    fn legend(&self) -> Vec<(String, Key)> {
        let mut entries: Vec<(String, Key)> =
            self.series.iter().map(|s| (s.label.clone(), Key::Line(colour(s.colour)))).collect();
        entries.push(("Pareto front".into(), Key::Front));
        if self.auto.is_some() {
            entries.push(("auto's pick".into(), Key::Auto));
        }
        if self.reference_error > 0.0 {
            entries.push(("reference's own error".into(), Key::Band));
        }
        entries
    }

    /// The whole image's size: the plot and the legend beside it.
    pub fn size(&self) -> (u32, u32) {
        let longest = self.legend().iter().map(|(l, _)| l.chars().count() as u32).max().unwrap_or(0);
        (SIZE.0 + 56 + LEGEND_CHAR * longest, SIZE.1)
    }

    /// The x range (log scale): every positive time with some margin. Points at 0 ms (a method
    /// with no shadow work) are drawn at its left end.
    fn x_range(&self) -> (f64, f64) {
        let times = self.series.iter().flat_map(|s| s.points.iter().map(|p| p.0)).filter(|&t| t > 0.0 && t.is_finite());
        let (lo, hi) = times.fold((f64::INFINITY, 0.0f64), |(lo, hi), t| (lo.min(t), hi.max(t)));
        if !lo.is_finite() {
            return (0.01, 1.0);
        }
        (lo / 2.0, (hi * 2.0).max(lo * 4.0))
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> DrawResult<DB> {
        root.fill(&WHITE)?;
        let (plot, legend) = root.split_horizontally(SIZE.0);
        let (x0, x1) = self.x_range();
        let y_max =
            self.series.iter().flat_map(|s| s.points.iter().map(|p| p.1)).filter(|e| e.is_finite()).fold(0.0, f64::max);
        let y1 = if y_max > 0.0 { y_max * 1.1 } else { 0.01 };
        let y1 = y1.max(self.reference_error * 1.5);
        let clamp = |(t, e): (f64, f64)| (t.max(x0), e);
        let mut chart = ChartBuilder::on(&plot)
            .caption(&self.title, ("sans-serif", 20))
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(72)
            .build_cartesian_2d((x0..x1).log_scale().with_key_points(log_ticks(x0, x1)), 0.0..y1)?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| format!("{v:.3}"))
            .label_style(("sans-serif", 14))
            .draw()?;
        if self.reference_error > 0.0 {
            let band = [(x0, 0.0), (x1, self.reference_error)];
            chart.draw_series(std::iter::once(Rectangle::new(band, BAND.mix(0.35).filled())))?;
        }
        for s in &self.series {
            let c = colour(s.colour);
            let points: Vec<(f64, f64)> = s.points.iter().copied().map(clamp).collect();
            chart.draw_series(LineSeries::new(points.clone(), c.stroke_width(2)))?;
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, c.filled())))?;
            // Each point's value along the axis, just above and right of it.
            let labelled = points.iter().zip(&s.point_labels);
            chart.draw_series(labelled.map(|(&p, text)| {
                EmptyElement::at(p) + Text::new(text.clone(), (6, -16), ("sans-serif", 12).into_font().color(&c))
            }))?;
        }
        let front: Vec<(f64, f64)> = self.front.iter().copied().map(clamp).collect();
        chart.draw_series(LineSeries::new(front.clone(), BLACK.stroke_width(1)))?;
        chart.draw_series(front.iter().map(|&p| Circle::new(p, 8, BLACK.stroke_width(2))))?;
        if let Some(p) = self.auto.map(clamp) {
            chart.draw_series(std::iter::once(Circle::new(p, 13, RING.stroke_width(3))))?;
        }
        // The legend beside the plot: every entry whole, however long.
        let font = ("sans-serif", LEGEND_FONT).into_font();
        for (k, (label, key)) in self.legend().iter().enumerate() {
            let y = 48 + 22 * k as i32;
            match key {
                Key::Line(c) => legend.draw(&PathElement::new(vec![(8, y), (32, y)], c.stroke_width(2)))?,
                Key::Front => legend.draw(&PathElement::new(vec![(8, y), (32, y)], BLACK.stroke_width(1)))?,
                Key::Auto => legend.draw(&Circle::new((20, y), 6, RING.stroke_width(2)))?,
                Key::Band => legend.draw(&Rectangle::new([(8, y - 6), (32, y + 6)], BAND.mix(0.35).filled()))?,
            }
            let style = font.clone().color(&BLACK).pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Left,
                plotters::style::text_anchor::VPos::Center,
            ));
            legend.draw(&Text::new(label.clone(), (40, y), style))?;
        }
        root.present()?;
        Ok(())
    }

    /// The chart as SVG text.
    pub fn svg(&self) -> Result<String, String> {
        let mut text = String::new();
        {
            let root = SVGBackend::with_string(&mut text, self.size()).into_drawing_area();
            self.draw(root).map_err(|e| format!("drawing the SVG chart: {e}"))?;
        }
        Ok(text)
    }

    /// The chart as PNG bytes.
    pub fn png(&self) -> Result<Vec<u8>, String> {
        let (w, h) = self.size();
        let mut rgb = vec![0u8; (w * h * 3) as usize];
        {
            let backend = GlyphBitmap(BitMapBackend::with_buffer(&mut rgb, (w, h)));
            self.draw(backend.into_drawing_area()).map_err(|e| format!("drawing the PNG chart: {e}"))?;
        }
        encode_png(&rgb, w, h)
    }

    /// `stem.svg` and `stem.png` in `dir` with their bytes, for `output::write_files_atomic`.
    pub fn files(&self, dir: &Path, stem: &str) -> Result<Vec<(std::path::PathBuf, Vec<u8>)>, String> {
        Ok(vec![
            (dir.join(format!("{stem}.svg")), self.svg()?.into_bytes()),
            (dir.join(format!("{stem}.png")), self.png()?),
        ])
    }

    /// Writes `stem.svg` and `stem.png` beside each other, both or neither.
    pub fn write(&self, dir: &Path, stem: &str) -> Result<(), String> {
        crate::output::write_files_atomic(&self.files(dir, stem)?).map_err(|e| e.to_string())
    }
}

use image::ImageEncoder as _;

/// RGB8 pixels, `width` x `height`, as PNG bytes (the charts' and the error pictures').
pub fn encode_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>, String> {
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| format!("encoding a PNG picture: {e}"))?;
    Ok(png)
}

/// Writes `bytes` to a temporary file beside `path`, then renames it to `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    crate::output::write_file_atomic(path, bytes).map_err(|e| format!("{}: {e}", path.display()))
}

mod glyphs {
    use plotters::prelude::*;
    use plotters_backend::text_anchor::{HPos, VPos};
    use plotters_backend::{
        BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingErrorKind, FontTransform,
    };

    /// A bitmap backend that draws text with the 8x8 glyphs of font8x8, scaled by whole pixels
    /// (`size / 12`, at least 1): everything else is the bitmap backend's own.
    pub struct GlyphBitmap<'a>(pub BitMapBackend<'a>);

    /// Glyph scale for a font size in pixels.
    fn glyph_scale(size: f64) -> i32 {
        ((size / 12.0).round() as i32).max(1)
    }

    /// The glyph of `c` (printable ASCII; anything else is `?`).
    fn glyph(c: char) -> [u8; 8] {
        let i = if c.is_ascii() && !c.is_ascii_control() { c as usize } else { '?' as usize };
        font8x8::legacy::BASIC_LEGACY[i]
    }

    impl DrawingBackend for GlyphBitmap<'_> {
        type ErrorType = <BitMapBackend<'static> as DrawingBackend>::ErrorType;

        fn get_size(&self) -> (u32, u32) {
            self.0.get_size()
        }
        fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.ensure_prepared()
        }
        fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.present()
        }
        fn draw_pixel(
            &mut self,
            point: BackendCoord,
            color: BackendColor,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_pixel(point, color)
        }
        fn draw_line<S: BackendStyle>(
            &mut self,
            from: BackendCoord,
            to: BackendCoord,
            style: &S,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_line(from, to, style)
        }
        fn draw_rect<S: BackendStyle>(
            &mut self,
            upper_left: BackendCoord,
            bottom_right: BackendCoord,
            style: &S,
            fill: bool,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_rect(upper_left, bottom_right, style, fill)
        }
        fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            path: I,
            style: &S,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_path(path, style)
        }
        fn draw_circle<S: BackendStyle>(
            &mut self,
            center: BackendCoord,
            radius: u32,
            style: &S,
            fill: bool,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_circle(center, radius, style, fill)
        }
        fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            vert: I,
            style: &S,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.fill_polygon(vert, style)
        }
        fn blit_bitmap(
            &mut self,
            pos: BackendCoord,
            size: (u32, u32),
            src: &[u8],
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.blit_bitmap(pos, size, src)
        }

        fn estimate_text_size<TStyle: BackendTextStyle>(
            &self,
            text: &str,
            style: &TStyle,
        ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
            let s = glyph_scale(style.size()) as u32;
            Ok((8 * s * text.chars().count() as u32, 8 * s))
        }

        fn draw_text<TStyle: BackendTextStyle>(
            &mut self,
            text: &str,
            style: &TStyle,
            pos: BackendCoord,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            let color = style.color();
            if color.alpha == 0.0 {
                return Ok(());
            }
            let s = glyph_scale(style.size());
            let (width, height) = (8 * s * text.chars().count() as i32, 8 * s);
            let dx = match style.anchor().h_pos {
                HPos::Left => 0,
                HPos::Right => -width,
                HPos::Center => -width / 2,
            };
            let dy = match style.anchor().v_pos {
                VPos::Top => 0,
                VPos::Center => -height / 2,
                VPos::Bottom => -height,
            };
            let transform = style.transform();
            let (w, h) = self.get_size();
            for (k, c) in text.chars().enumerate() {
                for (row, bits) in glyph(c).iter().enumerate() {
                    for col in 0..8 {
                        if bits & (1 << col) == 0 {
                            continue;
                        }
                        for (sx, sy) in (0..s).flat_map(|a| (0..s).map(move |b| (a, b))) {
                            let x = k as i32 * 8 * s + col * s + sx + dx;
                            let y = row as i32 * s + sy + dy;
                            let (x, y) = match &transform {
                                FontTransform::None => (x, y),
                                t => t.transform(x, y),
                            };
                            let (x, y) = (pos.0 + x, pos.1 + y);
                            if x >= 0 && y >= 0 && x < w as i32 && y < h as i32 {
                                self.0.draw_pixel((x, y), color)?;
                            }
                        }
                    }
                }
            }
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_axes_get_enough_ticks() {
        assert_eq!(log_ticks(0.5, 120.0), [0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0]);
        // About a decade and a half: 3 joins 1, 2 and 5.
        assert_eq!(log_ticks(2.4, 64.0), [3.0, 5.0, 10.0, 20.0, 30.0, 50.0]);
        // Less than a decade: every whole multiple.
        assert_eq!(log_ticks(2.5, 9.5), [3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
        assert!(log_ticks(0.0, 1.0).is_empty() && log_ticks(2.0, 1.0).is_empty());
    }

    /// The legend is beside the plot and as wide as its longest entry: no entry is cut, and
    /// each point carries its value; the reference's band shows where it has an error.
    #[test]
    fn legends_are_whole_and_points_are_labelled() {
        let long = "hybrid (hybrid.resolution+hybrid.margin+hybrid.radius)".to_owned();
        let chart = Chart {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![Series {
                label: long.clone(),
                colour: 4,
                points: vec![(3.0, 0.02), (6.0, 0.01)],
                point_labels: vec!["256".into(), "1024".into()],
            }],
            front: vec![(3.0, 0.02)],
            auto: Some((6.0, 0.01)),
            reference_error: 0.004,
        };
        let (w, h) = chart.size();
        assert_eq!(h, SIZE.1);
        assert!(w >= SIZE.0 + 40 + LEGEND_CHAR * long.chars().count() as u32, "{w}");
        let svg = chart.svg().unwrap();
        for text in [long.as_str(), "256", "1024", "Pareto front", "auto&apos;s pick", "reference&apos;s own error"] {
            assert!(svg.contains(text) || svg.contains(&text.replace("&apos;", "'")), "{text} in the SVG");
        }
        // The PNG draws the whole label: ink reaches past where the plot ends by the label's
        // width less a character or two.
        let png = image::load_from_memory(&chart.png().unwrap()).unwrap().to_rgb8();
        assert_eq!(png.dimensions(), (w, h));
        let rightmost = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| x >= SIZE.0 && png.get_pixel(x, y).0.iter().all(|&c| c < 64))
            .map(|(x, _)| x)
            .max()
            .unwrap();
        assert!(rightmost >= SIZE.0 + 40 + LEGEND_CHAR * (long.chars().count() as u32 - 2), "{rightmost}");
        assert!(rightmost < w, "inside the image");
    }
}
