//! A small, dependency-free SVG plotting module for `docs/accuracy.md`: log–log scatter and line
//! plots in one or more panels that share their axis ranges, with
//!
//! - the legend outside every plot area (a column right of the panels),
//! - axis titles with units and "log scale" in them, decade ticks labelled `10ⁿ`, minor ticks at
//!   2…9 × each decade,
//! - an optional Pareto front per panel (the non-dominated points of lower cost and lower value,
//!   drawn as a step line),
//! - point labels placed by a simple but real collision avoidance: each label's box (width
//!   estimated as characters × [`CHAR_WIDTH`] × font size) is tried right of its marker, left,
//!   above, below, then nudged vertically one label height at a time on either side (with a leader
//!   line); the first place that overlaps no placed label, no marker and stays inside the plot
//!   area wins. A label with no free place within [`MAX_NUDGES`] is left out and counted, and the
//!   plot says so under its panel.
//!
//! Every text a test needs to check geometry carries its box: labels are
//! `<text class="label" data-box="x y w h">`, legends `<rect class="legend-box">`, plot areas
//! `<rect class="plot-area">`, so a test can check that nothing overlaps without a font rasteriser.

use std::fmt::Write as _;

/// Estimated width of one character, as a fraction of the font size (sans-serif digits and
/// lower-case letters are ≈ 0.55; this errs wide).
pub const CHAR_WIDTH: f64 = 0.62;
/// Vertical nudges tried on each side before a label is left out.
pub const MAX_NUDGES: usize = 14;

const LABEL_FONT: f64 = 9.0;
const LABEL_H: f64 = 11.0;
const TICK_FONT: f64 = 11.0;
const PLOT_W: f64 = 470.0;
const PLOT_H: f64 = 330.0;
const LEFT: f64 = 78.0;
const RIGHT: f64 = 24.0;
const TOP: f64 = 34.0;
const BOTTOM: f64 = 62.0;
const TITLE_H: f64 = 44.0;
const LEGEND_GAP: f64 = 24.0;
const MARKER_R: f64 = 4.0;

/// The colours series cycle through (colour-blind-friendly "tab10").
pub const COLORS: [&str; 10] =
    ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];

/// A marker shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    /// ●
    Circle,
    /// ■
    Square,
    /// ▲
    Triangle,
    /// ◆
    Diamond,
    /// ▼
    TriangleDown,
    /// ✚
    Plus,
}

impl Marker {
    /// Every shape, in the order series use them.
    pub const ALL: [Marker; 6] =
        [Marker::Circle, Marker::Square, Marker::Triangle, Marker::Diamond, Marker::TriangleDown, Marker::Plus];
}

/// One point: position in data units and its label (empty: none).
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// x, data units (> 0 to be drawn).
    pub x: f64,
    /// y, data units (> 0 and finite to be drawn).
    pub y: f64,
    /// The label drawn beside the marker.
    pub label: String,
}

/// A series: its legend entry and its points.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Stroke and fill colour.
    pub color: String,
    /// Marker shape.
    pub marker: Marker,
    /// Filled marker (else hollow: white inside, coloured outline).
    pub filled: bool,
    /// Join the points with a line, in order.
    pub line: bool,
    /// The points.
    pub points: Vec<Point>,
}

/// One panel: a plot area with its title, axis titles and series.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Title above the plot area.
    pub title: String,
    /// x axis title (with units; "log scale" is appended).
    pub x_title: String,
    /// y axis title (with units; "log scale" is appended).
    pub y_title: String,
    /// The series.
    pub series: Vec<Series>,
    /// Draw the Pareto front of all this panel's points (lower x and lower y are better).
    pub pareto: bool,
}

/// A figure: panels on a grid of `columns`, sharing axis ranges, and one legend right of them.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// Title over the whole figure.
    pub title: String,
    /// Panels per row.
    pub columns: usize,
    /// The panels, row by row.
    pub panels: Vec<Panel>,
    /// Extra legend lines under the series entries (notes such as "hollow = raw scheme").
    pub legend_notes: Vec<String>,
}

/// An axis-aligned box `(x, y, w, h)` in SVG units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    /// Left.
    pub x: f64,
    /// Top.
    pub y: f64,
    /// Width.
    pub w: f64,
    /// Height.
    pub h: f64,
}

impl Rect {
    /// Whether two boxes overlap (touching edges do not).
    pub fn overlaps(&self, o: &Rect) -> bool {
        self.x < o.x + o.w && o.x < self.x + self.w && self.y < o.y + o.h && o.y < self.y + self.h
    }

    /// Whether `o` lies inside `self`.
    pub fn contains(&self, o: &Rect) -> bool {
        o.x >= self.x && o.y >= self.y && o.x + o.w <= self.x + self.w && o.y + o.h <= self.y + self.h
    }
}

/// Estimated width of `text` at `font` size.
pub fn text_width(text: &str, font: f64) -> f64 {
    text.chars().count() as f64 * font * CHAR_WIDTH
}

/// Escapes text for SVG.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// `10ⁿ` with Unicode superscripts.
fn decade_label(e: i32) -> String {
    const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = "10".to_owned();
    if e < 0 {
        s.push('⁻');
    }
    for d in e.unsigned_abs().to_string().bytes() {
        s.push(SUP[(d - b'0') as usize]);
    }
    s
}

fn drawable(p: &Point) -> bool {
    p.x > 0.0 && p.x.is_finite() && p.y > 0.0 && p.y.is_finite()
}

/// Indices (into `points`) of the Pareto front: no other point has both x ≤ and y ≤ with one
/// strictly smaller. Sorted by x.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut idx: Vec<usize> =
        (0..points.len()).filter(|&i| points[i].0.is_finite() && points[i].1.is_finite()).collect();
    idx.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0).then(points[a].1.total_cmp(&points[b].1)));
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for i in idx {
        if points[i].1 < best {
            best = points[i].1;
            front.push(i);
        }
    }
    front
}

/// Marker path centred on (x, y).
fn marker_svg(m: Marker, x: f64, y: f64, color: &str, filled: bool) -> String {
    let fill = if filled { color } else { "white" };
    let r = MARKER_R;
    let style = format!("fill=\"{fill}\" stroke=\"{color}\" stroke-width=\"1.4\"");
    match m {
        Marker::Circle => format!("<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"{r}\" {style}/>"),
        Marker::Square => {
            let s = r * 0.9;
            format!(
                "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{:.1}\" {style}/>",
                x - s,
                y - s,
                2.0 * s,
                2.0 * s
            )
        }
        Marker::Triangle => format!(
            "<path d=\"M{x:.1},{:.1} L{:.1},{:.1} L{:.1},{:.1} Z\" {style}/>",
            y - r * 1.1,
            x + r,
            y + r * 0.8,
            x - r,
            y + r * 0.8
        ),
        Marker::TriangleDown => format!(
            "<path d=\"M{x:.1},{:.1} L{:.1},{:.1} L{:.1},{:.1} Z\" {style}/>",
            y + r * 1.1,
            x + r,
            y - r * 0.8,
            x - r,
            y - r * 0.8
        ),
        Marker::Diamond => format!(
            "<path d=\"M{x:.1},{:.1} L{:.1},{y:.1} L{x:.1},{:.1} L{:.1},{y:.1} Z\" {style}/>",
            y - r * 1.2,
            x + r,
            y + r * 1.2,
            x - r
        ),
        Marker::Plus => format!(
            "<path d=\"M{:.1},{y:.1} H{:.1} M{x:.1},{:.1} V{:.1}\" stroke=\"{color}\" stroke-width=\"{}\" fill=\"none\"/>",
            x - r,
            x + r,
            y - r,
            y + r,
            if filled { 2.6 } else { 1.3 }
        ),
    }
}

/// Decade range `[lo, hi]` (exponents) covering `values`.
fn decades(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values {
        lo = lo.min(v.log10());
        hi = hi.max(v.log10());
    }
    if lo > hi {
        return (0.0, 1.0);
    }
    let (lo, hi) = (lo.floor(), hi.ceil());
    (lo, if hi > lo { hi } else { lo + 1.0 })
}

/// Renders `fig` to SVG text; the second value is the number of labels left out for lack of room.
pub fn render(fig: &Figure) -> (String, usize) {
    let cols = fig.columns.max(1);
    let rows = fig.panels.len().div_ceil(cols).max(1);
    let cell_w = LEFT + PLOT_W + RIGHT;
    let cell_h = TOP + PLOT_H + BOTTOM;
    let all = || fig.panels.iter().flat_map(|p| p.series.iter()).flat_map(|s| s.points.iter()).filter(|p| drawable(p));
    let (x0, x1) = decades(all().map(|p| p.x));
    let (y0, y1) = decades(all().map(|p| p.y));

    // The legend: unique (name, colour, marker, fill) entries in first-seen order.
    let mut entries: Vec<&Series> = Vec::new();
    for s in fig.panels.iter().flat_map(|p| p.series.iter()) {
        if !entries.iter().any(|e| e.name == s.name) {
            entries.push(s);
        }
    }
    let any_pareto = fig.panels.iter().any(|p| p.pareto);
    let legend_font = 11.0;
    let line_h = 16.0;
    let mut legend_lines: Vec<String> = entries.iter().map(|e| e.name.clone()).collect();
    if any_pareto {
        legend_lines.push("Pareto front".into());
    }
    legend_lines.extend(fig.legend_notes.iter().cloned());
    let legend_w = 34.0 + legend_lines.iter().map(|l| text_width(l, legend_font)).fold(0.0, f64::max) + 10.0;
    let legend_h = 12.0 + line_h * legend_lines.len() as f64;
    let legend_x = cols as f64 * cell_w + LEGEND_GAP;
    let legend_y = TITLE_H + TOP;
    let width = (legend_x + legend_w + 12.0).max(text_width(&fig.title, 15.0) + 40.0);
    let height = (TITLE_H + rows as f64 * cell_h).max(legend_y + legend_h + 12.0);

    let mut s = String::new();
    let _ = writeln!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width:.0}\" height=\"{height:.0}\" viewBox=\"0 0 {width:.0} {height:.0}\" font-family=\"DejaVu Sans, Verdana, sans-serif\" font-size=\"{TICK_FONT}\">"
    );
    let _ = writeln!(s, "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>");
    let _ = writeln!(
        s,
        "<text class=\"title\" x=\"20\" y=\"28\" font-size=\"15\" font-weight=\"bold\">{}</text>",
        esc(&fig.title)
    );

    let mut omitted = 0;
    for (pi, panel) in fig.panels.iter().enumerate() {
        let ox = (pi % cols) as f64 * cell_w;
        let oy = TITLE_H + (pi / cols) as f64 * cell_h;
        let area = Rect { x: ox + LEFT, y: oy + TOP, w: PLOT_W, h: PLOT_H };
        let px = |x: f64| area.x + (x.log10() - x0) / (x1 - x0) * area.w;
        let py = |y: f64| area.y + area.h - (y.log10() - y0) / (y1 - y0) * area.h;
        let _ = writeln!(s, "<g class=\"panel\">");
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" font-size=\"13\" font-weight=\"bold\">{}</text>",
            area.x + area.w / 2.0,
            oy + TOP - 10.0,
            esc(&panel.title)
        );
        // Grid and ticks.
        for e in x0 as i32..=x1 as i32 {
            for k in 1..=9 {
                let v = (e as f64) + (k as f64).log10();
                if v > x1 + 1e-9 || (k > 1 && e == x1 as i32) {
                    continue;
                }
                let x = area.x + (v - x0) / (x1 - x0) * area.w;
                let (stroke, len) = if k == 1 { ("#cccccc", 6.0) } else { ("#eeeeee", 3.0) };
                let _ = writeln!(
                    s,
                    "<line x1=\"{x:.1}\" y1=\"{:.1}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"{stroke}\"/><line x1=\"{x:.1}\" y1=\"{:.1}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"black\"/>",
                    area.y,
                    area.y + area.h,
                    area.y + area.h,
                    area.y + area.h + len
                );
                if k == 1 {
                    let _ = writeln!(
                        s,
                        "<text class=\"tick\" x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
                        area.y + area.h + 20.0,
                        decade_label(e)
                    );
                }
            }
        }
        for e in y0 as i32..=y1 as i32 {
            for k in 1..=9 {
                let v = (e as f64) + (k as f64).log10();
                if v > y1 + 1e-9 || (k > 1 && e == y1 as i32) {
                    continue;
                }
                let y = area.y + area.h - (v - y0) / (y1 - y0) * area.h;
                let (stroke, len) = if k == 1 { ("#cccccc", 6.0) } else { ("#eeeeee", 3.0) };
                let _ = writeln!(
                    s,
                    "<line x1=\"{:.1}\" y1=\"{y:.1}\" x2=\"{:.1}\" y2=\"{y:.1}\" stroke=\"{stroke}\"/><line x1=\"{:.1}\" y1=\"{y:.1}\" x2=\"{:.1}\" y2=\"{y:.1}\" stroke=\"black\"/>",
                    area.x,
                    area.x + area.w,
                    area.x - len,
                    area.x
                );
                if k == 1 {
                    let _ = writeln!(
                        s,
                        "<text class=\"tick\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
                        area.x - 9.0,
                        y + 4.0,
                        decade_label(e)
                    );
                }
            }
        }
        let _ = writeln!(
            s,
            "<rect class=\"plot-area\" x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"none\" stroke=\"black\"/>",
            area.x, area.y, area.w, area.h
        );
        let _ = writeln!(
            s,
            "<text class=\"axis-title\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{} — log scale</text>",
            area.x + area.w / 2.0,
            area.y + area.h + 42.0,
            esc(&panel.x_title)
        );
        let (tx, ty) = (ox + 18.0, area.y + area.h / 2.0);
        let _ = writeln!(
            s,
            "<text class=\"axis-title\" x=\"{tx:.1}\" y=\"{ty:.1}\" transform=\"rotate(-90 {tx:.1} {ty:.1})\" text-anchor=\"middle\">{} — log scale</text>",
            esc(&panel.y_title)
        );

        // Pareto front (under the markers).
        let pts: Vec<(f64, f64)> =
            panel.series.iter().flat_map(|s| s.points.iter()).filter(|p| drawable(p)).map(|p| (p.x, p.y)).collect();
        if panel.pareto {
            let front = pareto_front(&pts);
            if let Some(&first) = front.first() {
                let mut d = format!("M{:.1},{:.1}", px(pts[first].0), py(pts[first].1));
                for w in front.windows(2) {
                    let _ = write!(d, " H{:.1} V{:.1}", px(pts[w[1]].0), py(pts[w[1]].1));
                }
                let _ = write!(d, " H{:.1}", area.x + area.w);
                let _ = writeln!(
                    s,
                    "<path class=\"pareto\" d=\"{d}\" fill=\"none\" stroke=\"#444444\" stroke-width=\"2\" stroke-dasharray=\"6 3\" opacity=\"0.8\"/>"
                );
            }
        }
        // Lines and markers.
        let mut obstacles: Vec<Rect> = Vec::new();
        for series in &panel.series {
            let drawn: Vec<&Point> = series.points.iter().filter(|p| drawable(p)).collect();
            if series.line && drawn.len() > 1 {
                let line: Vec<String> = drawn.iter().map(|p| format!("{:.1},{:.1}", px(p.x), py(p.y))).collect();
                let _ = writeln!(
                    s,
                    "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"/>",
                    line.join(" "),
                    series.color
                );
            }
            for p in drawn {
                let (x, y) = (px(p.x), py(p.y));
                let _ = writeln!(s, "{}", marker_svg(series.marker, x, y, &series.color, series.filled));
                obstacles.push(Rect {
                    x: x - MARKER_R - 1.0,
                    y: y - MARKER_R - 1.0,
                    w: 2.0 * MARKER_R + 2.0,
                    h: 2.0 * MARKER_R + 2.0,
                });
            }
        }
        // Labels: the Pareto front's first (they matter most), then the rest in order.
        let mut order: Vec<(f64, f64, &str, &str)> = Vec::new();
        let labelled: Vec<(&Point, &str)> = panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(move |p| (p, s.color.as_str())))
            .filter(|(p, _)| drawable(p) && !p.label.is_empty())
            .collect();
        let front: Vec<usize> = if panel.pareto {
            pareto_front(&labelled.iter().map(|(p, _)| (p.x, p.y)).collect::<Vec<_>>())
        } else {
            Vec::new()
        };
        for &i in &front {
            order.push((px(labelled[i].0.x), py(labelled[i].0.y), &labelled[i].0.label, labelled[i].1));
        }
        for (i, (p, c)) in labelled.iter().enumerate() {
            if !front.contains(&i) {
                order.push((px(p.x), py(p.y), &p.label, c));
            }
        }
        let mut placed: Vec<Rect> = Vec::new();
        let mut panel_omitted = 0;
        for (x, y, label, color) in order {
            match place_label(x, y, label, &area, &placed, &obstacles) {
                Some((b, leader)) => {
                    if leader {
                        let (lx, ly) = (if b.x > x { b.x } else { b.x + b.w }, b.y + b.h / 2.0);
                        let _ = writeln!(
                            s,
                            "<line x1=\"{x:.1}\" y1=\"{y:.1}\" x2=\"{lx:.1}\" y2=\"{ly:.1}\" stroke=\"{color}\" stroke-width=\"0.6\" opacity=\"0.7\"/>"
                        );
                    }
                    let _ = writeln!(
                        s,
                        "<text class=\"label\" data-box=\"{:.1} {:.1} {:.1} {:.1}\" x=\"{:.1}\" y=\"{:.1}\" font-size=\"{LABEL_FONT}\" fill=\"#222222\">{}</text>",
                        b.x,
                        b.y,
                        b.w,
                        b.h,
                        b.x + 1.0,
                        b.y + b.h - 2.5,
                        esc(label)
                    );
                    placed.push(b);
                }
                None => panel_omitted += 1,
            }
        }
        if panel_omitted > 0 {
            let _ = writeln!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"10\" fill=\"#a00000\">{panel_omitted} point labels left out for lack of room (see the table)</text>",
                area.x,
                area.y + area.h + 56.0
            );
        }
        omitted += panel_omitted;
        let _ = writeln!(s, "</g>");
    }

    // The legend, right of every panel.
    let _ = writeln!(s, "<g class=\"legend\">");
    let _ = writeln!(
        s,
        "<rect class=\"legend-box\" x=\"{legend_x:.1}\" y=\"{legend_y:.1}\" width=\"{legend_w:.1}\" height=\"{legend_h:.1}\" fill=\"white\" stroke=\"#999999\"/>"
    );
    let mut ly = legend_y + 6.0 + line_h / 2.0;
    for e in &entries {
        let _ = writeln!(s, "{}", marker_svg(e.marker, legend_x + 16.0, ly, &e.color, e.filled));
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"{legend_font}\">{}</text>",
            legend_x + 30.0,
            ly + 4.0,
            esc(&e.name)
        );
        ly += line_h;
    }
    if any_pareto {
        let _ = writeln!(
            s,
            "<line x1=\"{:.1}\" y1=\"{ly:.1}\" x2=\"{:.1}\" y2=\"{ly:.1}\" stroke=\"#444444\" stroke-width=\"2\" stroke-dasharray=\"6 3\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"{legend_font}\">Pareto front</text>",
            legend_x + 6.0,
            legend_x + 26.0,
            legend_x + 30.0,
            ly + 4.0
        );
        ly += line_h;
    }
    for note in &fig.legend_notes {
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"{legend_font}\" fill=\"#444444\">{}</text>",
            legend_x + 8.0,
            ly + 4.0,
            esc(note)
        );
        ly += line_h;
    }
    let _ = writeln!(s, "</g>");
    s.push_str("</svg>\n");
    (s, omitted)
}

/// Finds a free box for `label` whose marker is at (x, y): right, left, above, below, then
/// vertical nudges right and left. Returns the box and whether it needs a leader line.
fn place_label(x: f64, y: f64, label: &str, area: &Rect, placed: &[Rect], obstacles: &[Rect]) -> Option<(Rect, bool)> {
    let w = text_width(label, LABEL_FONT) + 2.0;
    let h = LABEL_H;
    let gap = MARKER_R + 2.0;
    let mut candidates = vec![
        (Rect { x: x + gap, y: y - h / 2.0, w, h }, false),
        (Rect { x: x - gap - w, y: y - h / 2.0, w, h }, false),
        (Rect { x: x - w / 2.0, y: y - gap - h, w, h }, false),
        (Rect { x: x - w / 2.0, y: y + gap, w, h }, false),
    ];
    for k in 1..=MAX_NUDGES {
        for sign in [-1.0, 1.0] {
            let dy = sign * k as f64 * (h + 1.0);
            candidates.push((Rect { x: x + gap + 4.0, y: y - h / 2.0 + dy, w, h }, true));
            candidates.push((Rect { x: x - gap - 4.0 - w, y: y - h / 2.0 + dy, w, h }, true));
        }
    }
    candidates.into_iter().find(|(b, _)| {
        area.contains(b) && !placed.iter().any(|p| p.overlaps(b)) && !obstacles.iter().any(|o| o.overlaps(b))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_keeps_only_non_dominated_points_sorted_by_cost() {
        let pts = [(1.0, 5.0), (2.0, 3.0), (2.5, 4.0), (3.0, 1.0), (0.5, 9.0), (4.0, 1.0), (f64::INFINITY, 0.1)];
        assert_eq!(pareto_front(&pts), vec![4, 0, 1, 3]);
    }

    #[test]
    fn decade_labels_use_superscripts() {
        assert_eq!(decade_label(-5), "10⁻⁵");
        assert_eq!(decade_label(12), "10¹²");
        assert_eq!(decade_label(0), "10⁰");
    }

    #[test]
    fn crowded_labels_are_nudged_apart_not_stacked() {
        let points: Vec<Point> = (0..12)
            .map(|i| Point { x: 1.0 + 0.01 * i as f64, y: 1e-3 * (1.0 + 0.01 * i as f64), label: format!("p{i}") })
            .collect();
        let fig = Figure {
            title: "t".into(),
            columns: 1,
            panels: vec![Panel {
                title: "p".into(),
                x_title: "x (s)".into(),
                y_title: "y (m)".into(),
                series: vec![Series {
                    name: "s".into(),
                    color: COLORS[0].into(),
                    marker: Marker::Circle,
                    filled: true,
                    line: false,
                    points,
                }],
                pareto: true,
            }],
            legend_notes: vec![],
        };
        let (svg, omitted) = render(&fig);
        assert_eq!(omitted, 0);
        let boxes: Vec<Rect> = svg
            .lines()
            .filter_map(|l| l.split("data-box=\"").nth(1))
            .map(|rest| {
                let v: Vec<f64> =
                    rest.split('"').next().unwrap_or("").split(' ').filter_map(|t| t.parse().ok()).collect();
                Rect { x: v[0], y: v[1], w: v[2], h: v[3] }
            })
            .collect();
        assert_eq!(boxes.len(), 12);
        for (i, a) in boxes.iter().enumerate() {
            for b in &boxes[i + 1..] {
                assert!(!a.overlaps(b), "{a:?} overlaps {b:?}");
            }
        }
    }
}
