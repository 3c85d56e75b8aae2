//! A line plot as a PNG, for budget sweeps (`pmcodec eval --sweep --plot`): curves of a ratio
//! against a logarithmic x axis, with ticks, labels, reference lines and a legend, drawn into an
//! RGB raster with a built-in 5x7 font, so no plotting or font dependency is needed (the `png`
//! encoder is already in the tree through glTF's image decoding).

use thiserror::Error;

/// One curve: its legend label, colour and points `(x, y)`; points with a non-finite or
/// non-positive `x` or a non-finite `y` are left out.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Line colour, RGB.
    pub color: [u8; 3],
    /// The points, in drawing order.
    pub points: Vec<(f64, f64)>,
}

/// A horizontal reference line (a bar to stay under, or 1.0), dashed, labelled at its right end.
#[derive(Clone, Debug, PartialEq)]
pub struct Reference {
    /// Its y value.
    pub y: f64,
    /// Its label.
    pub label: String,
    /// Its colour.
    pub color: [u8; 3],
}

/// What a plot shows.
#[derive(Clone, Debug, PartialEq)]
pub struct Plot {
    /// Title above the axes.
    pub title: String,
    /// Label under the x axis (logarithmic).
    pub x_label: String,
    /// Label above the y axis.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
    /// Horizontal reference lines.
    pub references: Vec<Reference>,
}

/// Why a plot could not be drawn.
#[derive(Debug, Error)]
pub enum PlotError {
    /// No curve has a drawable point.
    #[error("nothing to plot: no series has a point with a positive finite x and a finite y")]
    Empty,
    /// The PNG encoder failed.
    #[error("encoding the PNG: {0}")]
    Png(#[from] png::EncodingError),
}

const WIDTH: usize = 960;
const HEIGHT: usize = 600;
/// Pixels per font dot.
const SCALE: usize = 2;
const LEFT: usize = 110;
const RIGHT: usize = 30;
const TOP: usize = 60;
const BOTTOM: usize = 80;

struct Canvas {
    rgb: Vec<u8>,
}

impl Canvas {
    fn new() -> Self {
        Canvas { rgb: vec![255; WIDTH * HEIGHT * 3] }
    }

    fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if (0..WIDTH as i64).contains(&x) && (0..HEIGHT as i64).contains(&y) {
            let i = (y as usize * WIDTH + x as usize) * 3;
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    /// A line `width` pixels thick; `dash` > 0 draws `dash` pixels on, `dash` off.
    fn line(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: [u8; 3], width: i64, dash: usize) {
        let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as usize;
        for s in 0..=steps {
            if dash > 0 && (s / dash) % 2 == 1 {
                continue;
            }
            let t = s as f64 / steps as f64;
            let (x, y) = ((x0 + t * (x1 - x0)).round() as i64, (y0 + t * (y1 - y0)).round() as i64);
            for dx in 0..width {
                for dy in 0..width {
                    self.set(x + dx - width / 2, y + dy - width / 2, c);
                }
            }
        }
    }

    fn square(&mut self, (x, y): (f64, f64), half: i64, c: [u8; 3]) {
        let (x, y) = (x.round() as i64, y.round() as i64);
        for dx in -half..=half {
            for dy in -half..=half {
                self.set(x + dx, y + dy, c);
            }
        }
    }

    /// Text with its top-left corner at (x, y); unknown characters are drawn as boxes.
    fn text(&mut self, x: usize, y: usize, s: &str, c: [u8; 3]) {
        for (k, ch) in s.chars().enumerate() {
            let rows = glyph(ch.to_ascii_lowercase());
            for (r, bits) in rows.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        for sx in 0..SCALE {
                            for sy in 0..SCALE {
                                let px = x + (k * 6 + col) * SCALE + sx;
                                let py = y + r * SCALE + sy;
                                self.set(px as i64, py as i64, c);
                            }
                        }
                    }
                }
            }
        }
    }
}

fn text_width(s: &str) -> usize {
    s.chars().count() * 6 * SCALE
}

/// The 5x7 dots of a character, one byte per row, bit 4 leftmost.
fn glyph(c: char) -> [u8; 7] {
    match c {
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        '.' => [0, 0, 0, 0, 0, 0x0C, 0x0C],
        ',' => [0, 0, 0, 0, 0x0C, 0x04, 0x08],
        '%' => [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03],
        '/' => [0, 0x01, 0x02, 0x04, 0x08, 0x10, 0],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '-' => [0, 0, 0, 0x1F, 0, 0, 0],
        '+' => [0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0],
        ':' => [0, 0x0C, 0x0C, 0, 0x0C, 0x0C, 0],
        '_' => [0, 0, 0, 0, 0, 0, 0x1F],
        '=' => [0, 0, 0x1F, 0, 0x1F, 0, 0],
        ' ' => [0; 7],
        'a' => [0, 0, 0x0E, 0x01, 0x0F, 0x11, 0x0F],
        'b' => [0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1E],
        'c' => [0, 0, 0x0E, 0x10, 0x10, 0x11, 0x0E],
        'd' => [0x01, 0x01, 0x0D, 0x13, 0x11, 0x11, 0x0F],
        'e' => [0, 0, 0x0E, 0x11, 0x1F, 0x10, 0x0E],
        'f' => [0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08],
        'g' => [0, 0x0F, 0x11, 0x11, 0x0F, 0x01, 0x0E],
        'h' => [0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11],
        'i' => [0x04, 0, 0x0C, 0x04, 0x04, 0x04, 0x0E],
        'j' => [0x02, 0, 0x06, 0x02, 0x02, 0x12, 0x0C],
        'k' => [0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12],
        'l' => [0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'm' => [0, 0, 0x1A, 0x15, 0x15, 0x11, 0x11],
        'n' => [0, 0, 0x16, 0x19, 0x11, 0x11, 0x11],
        'o' => [0, 0, 0x0E, 0x11, 0x11, 0x11, 0x0E],
        'p' => [0, 0, 0x1E, 0x11, 0x1E, 0x10, 0x10],
        'q' => [0, 0, 0x0D, 0x13, 0x0F, 0x01, 0x01],
        'r' => [0, 0, 0x16, 0x19, 0x10, 0x10, 0x10],
        's' => [0, 0, 0x0E, 0x10, 0x0E, 0x01, 0x1E],
        't' => [0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06],
        'u' => [0, 0, 0x11, 0x11, 0x11, 0x13, 0x0D],
        'v' => [0, 0, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'w' => [0, 0, 0x11, 0x11, 0x15, 0x15, 0x0A],
        'x' => [0, 0, 0x11, 0x0A, 0x04, 0x0A, 0x11],
        'y' => [0, 0, 0x11, 0x11, 0x0F, 0x01, 0x0E],
        'z' => [0, 0, 0x1F, 0x02, 0x04, 0x08, 0x1F],
        _ => [0x1F, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1F],
    }
}

/// A tick step of 1, 2, 2.5 or 5 times a power of ten giving at most 10 ticks over `span`.
fn tick_step(span: f64) -> f64 {
    let raw = span / 10.0;
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * p).find(|&s| s >= raw).unwrap_or(10.0 * p)
}

/// Ticks of a logarithmic axis between `lo` and `hi`: 1, 2 and 5 times powers of ten.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let mut out = Vec::new();
    let mut p = 10f64.powf(lo.log10().floor());
    while p <= hi * 1.0001 {
        for m in [1.0, 2.0, 5.0] {
            let t = m * p;
            if t >= lo * 0.9999 && t <= hi * 1.0001 {
                out.push(t);
            }
        }
        p *= 10.0;
    }
    out
}

fn label(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0');
    s.trim_end_matches('.').to_string()
}

/// Draws `plot` and returns the PNG file's bytes (960 x 600, RGB).
pub fn render_png(plot: &Plot) -> Result<Vec<u8>, PlotError> {
    let ok = |&(x, y): &(f64, f64)| x.is_finite() && x > 0.0 && y.is_finite();
    let points: Vec<(f64, f64)> = plot.series.iter().flat_map(|s| s.points.iter().copied().filter(ok)).collect();
    if points.is_empty() {
        return Err(PlotError::Empty);
    }
    let (mut x_lo, mut x_hi) = points.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    if x_hi <= x_lo {
        (x_lo, x_hi) = (x_lo / 2.0, x_hi * 2.0);
    }
    let ys = points.iter().map(|p| p.1).chain(plot.references.iter().map(|r| r.y).filter(|y| y.is_finite()));
    let (y_min, y_max) = ys.fold((f64::MAX, f64::MIN), |(a, b), y| (a.min(y), b.max(y)));
    let pad = ((y_max - y_min) * 0.05).max(0.02);
    let step0 = tick_step((y_max - y_min + 2.0 * pad).max(1e-9));
    let (y_lo, y_hi) = (((y_min - pad) / step0).floor() * step0, ((y_max + pad) / step0).ceil() * step0);
    let step = tick_step(y_hi - y_lo);
    let (pw, ph) = ((WIDTH - LEFT - RIGHT) as f64, (HEIGHT - TOP - BOTTOM) as f64);
    let to_px = |x: f64, y: f64| {
        let fx = (x.ln() - x_lo.ln()) / (x_hi.ln() - x_lo.ln());
        let fy = (y - y_lo) / (y_hi - y_lo);
        (LEFT as f64 + fx * pw, TOP as f64 + (1.0 - fy) * ph)
    };
    let mut c = Canvas::new();
    let (grid, axis, ink) = ([225, 225, 225], [60, 60, 60], [20, 20, 20]);
    // Grid and ticks.
    let mut y = (y_lo / step).ceil() * step;
    while y <= y_hi + step * 1e-6 {
        let (_, py) = to_px(x_lo, y);
        c.line((LEFT as f64, py), (LEFT as f64 + pw, py), grid, 1, 0);
        c.line((LEFT as f64 - 6.0, py), (LEFT as f64, py), axis, 2, 0);
        let l = label(y);
        c.text(LEFT.saturating_sub(12 + text_width(&l)), (py as usize).saturating_sub(7), &l, ink);
        y += step;
    }
    for x in log_ticks(x_lo, x_hi) {
        let (px, _) = to_px(x, y_lo);
        c.line((px, TOP as f64), (px, TOP as f64 + ph), grid, 1, 0);
        c.line((px, TOP as f64 + ph), (px, TOP as f64 + ph + 6.0), axis, 2, 0);
        let l = label(x);
        c.text((px as usize).saturating_sub(text_width(&l) / 2), TOP + ph as usize + 12, &l, ink);
    }
    // Axes.
    c.line((LEFT as f64, TOP as f64), (LEFT as f64, TOP as f64 + ph), axis, 2, 0);
    c.line((LEFT as f64, TOP as f64 + ph), (LEFT as f64 + pw, TOP as f64 + ph), axis, 2, 0);
    // Reference lines.
    for r in plot.references.iter().filter(|r| r.y.is_finite()) {
        let (_, py) = to_px(x_lo, r.y);
        c.line((LEFT as f64, py), (LEFT as f64 + pw, py), r.color, 2, 8);
        c.text((LEFT + pw as usize).saturating_sub(text_width(&r.label) + 4), (py as usize).saturating_sub(18), &r.label, r.color);
    }
    // Curves with a marker at every point.
    for s in &plot.series {
        let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(ok).map(|(x, y)| to_px(x, y)).collect();
        for w in pts.windows(2) {
            c.line(w[0], w[1], s.color, 3, 0);
        }
        for &p in &pts {
            c.square(p, 4, s.color);
        }
    }
    // Titles and legend.
    c.text(LEFT, 14, &plot.title, ink);
    c.text(14, TOP - 26, &plot.y_label, ink);
    c.text(LEFT + (pw as usize).saturating_sub(text_width(&plot.x_label)) / 2, HEIGHT - 34, &plot.x_label, ink);
    for (k, s) in plot.series.iter().enumerate() {
        let y = TOP + 14 + k * 24;
        c.line((LEFT as f64 + 16.0, y as f64 + 7.0), (LEFT as f64 + 46.0, y as f64 + 7.0), s.color, 3, 0);
        c.text(LEFT + 54, y, &s.label, s.color);
    }
    let mut bytes = Vec::new();
    let mut enc = png::Encoder::new(&mut bytes, WIDTH as u32, HEIGHT as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header()?;
    w.write_image_data(&c.rgb)?;
    w.finish()?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks() {
        assert_eq!(log_ticks(1.0, 50.0), vec![1.0, 2.0, 5.0, 10.0, 20.0, 50.0]);
        assert_eq!(tick_step(1.0), 0.1);
        assert_eq!(tick_step(2.2), 0.25);
        assert_eq!(label(1.15), "1.15");
        assert_eq!(label(2.0), "2");
    }

    #[test]
    fn draws_curves_and_refuses_nothing() {
        let plot = Plot {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![Series { label: "a".into(), color: [200, 0, 0], points: vec![(1.0, 1.1), (10.0, 0.9), (50.0, f64::NAN)] }],
            references: vec![Reference { y: 1.15, label: "bar".into(), color: [0, 0, 200] }],
        };
        let bytes = render_png(&plot).expect("renders");
        let mut r = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().expect("a PNG");
        let mut buf = vec![0; r.output_buffer_size().expect("size")];
        let info = r.next_frame(&mut buf).expect("a frame");
        assert_eq!((info.width, info.height), (WIDTH as u32, HEIGHT as u32));
        // The curve's colour is on the canvas.
        assert!(buf.chunks(3).any(|p| p == [200, 0, 0]));
        let empty = Plot { series: vec![Series { label: "a".into(), color: [0; 3], points: vec![(0.0, 1.0)] }], ..plot };
        assert!(matches!(render_png(&empty), Err(PlotError::Empty)));
    }
}
