//! The charts, drawn on any plotters backend (PNG and SVG).

use super::*;

/// The charts, each drawn on any plotters backend.
pub(crate) enum Chart<'a> {
    WorkPrecision {
        caption: &'a str,
        y_desc: &'a str,
        runs: &'a [&'a Run],
        /// Energy error instead of the trajectory error (no IFToMM levels).
        energy: bool,
    },
    Stability(&'a Config, &'a [Cell]),
    Penalty(&'a Config, &'a [MapCell]),
    Singular(&'a Config, &'a [MapCell]),
    Scaling(&'a [Cost]),
    /// Trajectory error against the substep h (the order of each method).
    Convergence {
        caption: &'a str,
        runs: &'a [&'a Run],
    },
}

impl Chart<'_> {
    /// Draws `name.png` and `name.svg` into `out`.
    pub(crate) fn save(
        &self,
        out: &Path,
        name: &str,
        size: (u32, u32),
        files: &mut Vec<String>,
    ) -> DynResult<()> {
        let png = out.join(format!("{name}.png"));
        self.draw(BitMapBackend::new(&png, size).into_drawing_area())?;
        let svg = out.join(format!("{name}.svg"));
        self.draw(SVGBackend::new(&svg, size).into_drawing_area())?;
        files.push(format!("{name}.png"));
        files.push(format!("{name}.svg"));
        Ok(())
    }

    pub(crate) fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> DynResult<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        match self {
            Chart::WorkPrecision {
                caption,
                y_desc,
                runs,
                energy,
            } => work_precision(&root, caption, y_desc, runs, *energy)?,
            Chart::Stability(cfg, cells) => draw_stability(&root, cfg, cells)?,
            Chart::Penalty(cfg, cells) => draw_penalty(&root, cfg, cells)?,
            Chart::Singular(cfg, cells) => draw_singular(&root, cfg, cells)?,
            Chart::Scaling(costs) => draw_scaling(&root, costs)?,
            Chart::Convergence { caption, runs } => draw_convergence(&root, caption, runs)?,
        }
        root.present()?;
        Ok(())
    }
}

/// Per method, the smallest trajectory error at each substep size `h = dt / substeps` (ok runs).
pub(crate) fn by_substep(runs: &[&Run], method: Method) -> Vec<(f64, f64)> {
    let mut pts: Vec<(f64, f64)> = Vec::new();
    for r in runs
        .iter()
        .filter(|r| r.method == method && r.ok() && r.tol.is_none())
    {
        let h = r.dt / r.substeps as f64;
        let e = r.traj.max(ERR_FLOOR);
        match pts.iter_mut().find(|(x, _)| (x / h - 1.0).abs() < 1e-9) {
            Some(p) => p.1 = p.1.min(e),
            None => pts.push((h, e)),
        }
    }
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts
}

/// Observed order: the least-squares slope of log(error) against log(h) over the points with
/// an error above `floor` and out of the method's own error floor: above 100 times its best
/// error if that leaves three points, else 10 times, else all above `floor` (a fourth-order
/// method reaches the projection's 1e-10 m within a few halvings, and the flat tail would
/// pull its slope down: A01 fitted 2.9 with the tail, 4.0 without). A method whose best error
/// is below `floor` is fitted only at substeps no finer than that best error's: past it the
/// error grows again as `h` shrinks (each substep's projection leaves up to its 1e-10 m
/// tolerance, and more substeps leave more of it), which is no truncation error. The conical
/// pendulum's fourth order falls by 16.1 to 16.3 per halved `h` from 1.1e-5 m at 1/30 s to
/// 1.1e-11 m at 1/960 s, reaches 4.0e-13 m at 1/1920 s and rises to 1.7e-9 m at 1/7680 s;
/// with that last point in, the fit said 1.41. A method that stops converging above `floor`
/// (a soft penalty's elastic gap) keeps every point. NaN with fewer than two points.
pub(crate) fn observed_order(pts: &[(f64, f64)], floor: f64) -> f64 {
    let (h_min, best) = pts
        .iter()
        .fold((0.0, f64::INFINITY), |a, q| if q.1 < a.1 { *q } else { a });
    let h_best = if best < floor { h_min } else { 0.0 };
    let above = move |lim: f64| {
        pts.iter()
            .filter(move |(h, e)| *h >= h_best && *e > lim.max(floor))
    };
    let lim = [100.0, 10.0]
        .into_iter()
        .map(|k| k * best)
        .find(|&lim| above(lim).count() >= 3)
        .unwrap_or(floor);
    let p: Vec<(f64, f64)> = above(lim).map(|(h, e)| (h.ln(), e.ln())).collect();
    if p.len() < 2 {
        return f64::NAN;
    }
    let n = p.len() as f64;
    let (mx, my) = (
        p.iter().map(|q| q.0).sum::<f64>() / n,
        p.iter().map(|q| q.1).sum::<f64>() / n,
    );
    let sxy: f64 = p.iter().map(|q| (q.0 - mx) * (q.1 - my)).sum();
    let sxx: f64 = p.iter().map(|q| (q.0 - mx) * (q.0 - mx)).sum();
    sxy / sxx
}

pub(crate) fn draw_convergence<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    caption: &str,
    runs: &[&Run],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let all: Vec<(Method, Vec<(f64, f64)>)> = methods_in(runs)
        .iter()
        .map(|m| (*m, by_substep(runs, *m)))
        .filter(|(_, p)| !p.is_empty())
        .collect();
    let hs = all.iter().flat_map(|(_, p)| p.iter().map(|q| q.0));
    let (x0, x1) = hs.fold((f64::INFINITY, 0.0f64), |(a, b), h| (a.min(h), b.max(h)));
    let (x0, x1) = (x0 / 1.5, x1 * 1.5);
    let es: Vec<f64> = all
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.1))
        .collect();
    let y0 = es.iter().copied().fold(1e-4, f64::min) / 3.0;
    let y1 = es.iter().copied().fold(1.0, f64::max) * 5.0;
    let mut chart = ChartBuilder::on(root)
        .caption(caption, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("substep h (s)")
        .y_desc("trajectory error (m), best run at each h")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    // Slope guides through the coarsest point of the first- and second-order Lagrange runs.
    let gray = RGBColor(120, 120, 120);
    for (method, slope) in [(Method::Lagrange, 1.0), (Method::Rattle, 2.0)] {
        if let Some((_, p)) = all.iter().find(|(m, _)| *m == method)
            && let Some(&(h, e)) = p.last()
        {
            let at = |x: f64| e * 2.0 * (x / h).powf(slope);
            chart.draw_series(LineSeries::new(
                [(x0, at(x0).max(y0)), (h, at(h))],
                gray.stroke_width(1),
            ))?;
            chart.draw_series(std::iter::once(Text::new(
                format!("slope {slope:.0}"),
                (h / 1.4, at(h) * 1.6),
                ("sans-serif", 13).into_font().color(&gray),
            )))?;
        }
    }
    for (method, pts) in &all {
        let c = method.color();
        let order = observed_order(pts, 1e-9);
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))?
            .label(format!("{} (order {order:.2})", method.name()))
            .legend(move |(x, yy)| PathElement::new([(x, yy), (x + 20, yy)], c.stroke_width(3)));
        chart.draw_series(pts.iter().map(|&q| Circle::new(q, 3, c.filled())))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()?;
    Ok(())
}

/// Runs on the Pareto front (no other run both cheaper and more accurate), by CPU time.
pub(crate) fn pareto<'a>(
    runs: impl Iterator<Item = &'a Run>,
    y: impl Fn(&Run) -> f64,
) -> Vec<&'a Run> {
    let mut ok: Vec<&Run> = runs.filter(|r| r.ok() && y(r).is_finite()).collect();
    ok.sort_by(|a, b| a.cpu.total_cmp(&b.cpu));
    let mut best = f64::INFINITY;
    let mut front = Vec::new();
    for r in ok {
        if y(r) < best {
            best = y(r);
            front.push(r);
        }
    }
    front
}

/// A chart with logarithmic axes.
type LogChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>;

/// Floor of plotted errors (a run can hit zero to rounding).
pub(crate) const ERR_FLOOR: f64 = 1e-13;

/// The work-precision chart's guides: the IFToMM precision levels (trajectory error only), the
/// real-time line and the band of failed runs at `fail_y`; `[x0, x1, y0, y1]` the axes' extent.
fn draw_guides<DB: DrawingBackend>(
    chart: &mut LogChart<'_, DB>,
    [x0, x1, y0, y1]: [f64; 4],
    fail_y: f64,
    energy: bool,
    points: &[(f64, f64)],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let gray = RGBColor(110, 110, 110);
    if !energy {
        for (level, label) in [
            (1e-1, "IFToMM low precision 1e-1 m"),
            (1e-3, "IFToMM high precision 1e-3 m"),
        ] {
            if level > y0 && level < y1 {
                chart.draw_series(LineSeries::new(
                    [(x0, level), (x1, level)],
                    gray.stroke_width(1),
                ))?;
                let x = label_spot(points, [x0, x1, y0, y1], level * 1.25);
                chart.draw_series(std::iter::once(Text::new(
                    label,
                    (x, level * 1.25),
                    ("sans-serif", 13).into_font().color(&gray),
                )))?;
            }
        }
    }
    if 1.0 > x0 && 1.0 < x1 {
        chart.draw_series(LineSeries::new(
            [(1.0, y0), (1.0, y1)],
            BLACK.stroke_width(1),
        ))?;
        chart.draw_series(std::iter::once(Text::new(
            "real time",
            (1.08, y0 * 2.0),
            ("sans-serif", 13).into_font(),
        )))?;
    }
    // Failed runs: crosses along the top at their CPU time.
    chart.draw_series(LineSeries::new(
        [(x0, fail_y / 1.6), (x1, fail_y / 1.6)],
        RGBColor(220, 220, 220).stroke_width(1),
    ))?;
    let x = label_spot(points, [x0, x1, y0, y1], fail_y * 1.35);
    chart.draw_series(std::iter::once(Text::new(
        "failed runs (x)",
        (x, fail_y * 1.35),
        ("sans-serif", 13).into_font().color(&gray),
    )))?;
    Ok(())
}

/// Where a guide's label (left-aligned, about 0.25 of the plot wide, hanging 0.04 of its height
/// below its anchor at height `y`, as plotters draws text) covers the fewest data points and
/// stays off the legend (upper right): the x of the best of fourteen positions along the axis,
/// the leftmost among equals.
fn label_spot(points: &[(f64, f64)], [x0, x1, y0, y1]: [f64; 4], y: f64) -> f64 {
    let fx = |x: f64| (x / x0).ln() / (x1 / x0).ln();
    let fy = |v: f64| (v / y0).ln() / (y1 / y0).ln();
    // A point's dot is about 0.01 of the plot across: margins of that much.
    let (bottom, top) = (fy(y) - 0.05, fy(y) + 0.01);
    let cost = |left: f64| {
        let right = left + 0.27;
        let covered = points
            .iter()
            .filter(|&&(px, py)| {
                (left - 0.01..right).contains(&fx(px)) && (bottom..top).contains(&fy(py))
            })
            .count();
        // The legend box: the upper right quarter, roughly.
        let legend = right > 0.74 && top > 0.55;
        covered + if legend { 1000 } else { 0 }
    };
    let best = (0..14)
        .map(|k| 0.01 + 0.05 * f64::from(k))
        .min_by_key(|&f| cost(f))
        .unwrap_or(0.01);
    x0 * (x1 / x0).powf(best)
}

/// Each method's runs: its Pareto line, its successful runs as dots, its failed runs as crosses
/// along the top.
fn draw_methods<DB: DrawingBackend>(
    chart: &mut LogChart<'_, DB>,
    shown: &[&Run],
    x0: f64,
    fail_y: f64,
    energy: bool,
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let y = |r: &Run| (if energy { r.energy } else { r.traj }).max(ERR_FLOOR);
    for method in methods_in(shown) {
        let mine: Vec<&Run> = shown
            .iter()
            .copied()
            .filter(|r| r.method == method)
            .collect();
        if mine.is_empty() {
            continue;
        }
        let c = method.color();
        let front = pareto(mine.iter().copied(), y);
        chart
            .draw_series(LineSeries::new(
                front.iter().map(|r| (r.cpu, y(r))),
                c.stroke_width(2),
            ))?
            .label(method.name())
            .legend(move |(x, yy)| PathElement::new([(x, yy), (x + 20, yy)], c.stroke_width(3)));
        chart.draw_series(
            mine.iter()
                .filter(|r| r.ok())
                .map(|r| Circle::new((r.cpu, y(r)), 3, c.filled())),
        )?;
        chart.draw_series(
            mine.iter()
                .filter(|r| r.failed())
                .map(|r| Cross::new((r.cpu.max(x0), fail_y), 5, c.stroke_width(2))),
        )?;
    }
    Ok(())
}

pub(crate) fn work_precision<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    caption: &str,
    y_desc: &str,
    runs: &[&Run],
    energy: bool,
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let y = |r: &Run| (if energy { r.energy } else { r.traj }).max(ERR_FLOOR);
    let shown: Vec<&Run> = runs
        .iter()
        .copied()
        .filter(|r| !r.status.starts_with("skipped"))
        .collect();
    let cpus: Vec<f64> = shown.iter().map(|r| r.cpu).filter(|c| *c > 0.0).collect();
    let (x0, x1) = cpus
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), c| (a.min(*c), b.max(*c)));
    let (x0, x1) = ((x0.min(0.5) / 2.0).max(1e-4), (x1.max(2.0) * 2.0));
    let ok_errs: Vec<f64> = shown.iter().filter(|r| r.ok()).map(|r| y(r)).collect();
    let y0 = ok_errs.iter().copied().fold(1e-4, f64::min) / 3.0;
    let y_top_data = ok_errs.iter().copied().fold(1.0, f64::max);
    let y1 = y_top_data * 30.0;
    let fail_y = y_top_data * 10.0;
    let mut chart = ChartBuilder::on(root)
        .caption(caption, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("CPU s per simulated s (single thread, stepping loop only)")
        .y_desc(y_desc)
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    let points: Vec<(f64, f64)> = shown
        .iter()
        .map(|r| {
            if r.failed() {
                (r.cpu.max(x0), fail_y)
            } else {
                (r.cpu, y(r))
            }
        })
        .collect();
    draw_guides(&mut chart, [x0, x1, y0, y1], fail_y, energy, &points)?;
    draw_methods(&mut chart, &shown, x0, fail_y, energy)?;
    let front = pareto(shown.iter().copied(), y);
    chart
        .draw_series(
            front
                .iter()
                .map(|r| Circle::new((r.cpu, y(r)), 7, BLACK.stroke_width(1))),
        )?
        .label("Pareto front (all methods)")
        .legend(|(x, yy)| Circle::new((x + 10, yy), 6, BLACK.stroke_width(1)));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()?;
    Ok(())
}

/// Rows and columns of the maps' per-method panels: room for every method of [`METHODS`].
const METHOD_GRID: (usize, usize) = (METHODS.len().div_ceil(4), 4);

pub(crate) fn draw_stability<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    cfg: &Config,
    cells: &[Cell],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let title = format!(
        "chain of {} links, dt 1/60, {} s: end-mass ratio x substeps (green ok, orange gap > 1 cm, red blew up, grey skipped)",
        cfg.stability_links, cfg.stability_secs
    );
    let (top, body) = root.split_vertically(40);
    top.draw(&Text::new(title, (10, 12), ("sans-serif", 15).into_font()))?;
    let panels = body.split_evenly(METHOD_GRID);
    let nr = cfg.stability_ratios.len() as i32;
    let ns = cfg.substeps.len() as i32;
    for (panel, method) in panels.iter().zip(METHODS) {
        let mut chart = ChartBuilder::on(panel)
            .caption(method.name(), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(0f64..ns as f64, 0f64..nr as f64)?;
        let subs = cfg.substeps.clone();
        let ratios = cfg.stability_ratios.clone();
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(ns as usize * 2 + 1)
            .y_labels(nr as usize * 2 + 1)
            .x_label_formatter(&|x| {
                let i = (x - 0.5).round();
                if (x - 0.5 - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < subs.len() {
                    format!("{}", subs[i as usize])
                } else {
                    String::new()
                }
            })
            .y_label_formatter(&|y| {
                let i = (y - 0.5).round();
                if (y - 0.5 - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < ratios.len() {
                    format!("1:{}", ratios[i as usize])
                } else {
                    String::new()
                }
            })
            .x_desc("substeps")
            .y_desc("end-mass ratio")
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 12))
            .draw()?;
        for (i, &sub) in cfg.substeps.iter().enumerate() {
            for (j, &ratio) in cfg.stability_ratios.iter().enumerate() {
                let cell = cells
                    .iter()
                    .find(|c| c.method == method && c.ratio == ratio && c.substeps == sub);
                let (color, label) = match cell {
                    None => (RGBColor(240, 240, 240), "n/a".to_string()),
                    Some(c) => match c.class {
                        "ok" => (RGBColor(120, 200, 120), format!("{:.0e}", c.gap)),
                        "gap" => (RGBColor(250, 170, 70), format!("{:.0e}", c.gap)),
                        "blew up" => (RGBColor(220, 70, 60), "blew up".into()),
                        _ => (RGBColor(190, 190, 190), "skipped".into()),
                    },
                };
                let (x, y) = (i as f64, j as f64);
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(x + 0.03, y + 0.03), (x + 0.97, y + 0.97)],
                    color.filled(),
                )))?;
                chart.draw_series(std::iter::once(Text::new(
                    label,
                    (x + 0.12, y + 0.6),
                    ("sans-serif", 12).into_font(),
                )))?;
            }
        }
    }
    Ok(())
}

/// The least-squares slope of `log(cost)` against `log(N)` (at least two sizes).
pub(crate) fn cost_exponent(pts: &[(f64, f64)]) -> Option<f64> {
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let (lx, ly): (Vec<f64>, Vec<f64>) = pts.iter().map(|&(x, y)| (x.ln(), y.ln())).unzip();
    let (mx, my) = (lx.iter().sum::<f64>() / n, ly.iter().sum::<f64>() / n);
    let sxy: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = lx.iter().map(|x| (x - mx).powi(2)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

pub(crate) fn draw_scaling<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    costs: &[Cost],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let n1 = costs.iter().map(|c| c.n).max().unwrap_or(10) as f64;
    let (y0, y1) = costs.iter().fold((f64::INFINITY, 0.0f64), |(a, b), c| {
        (a.min(c.us_per_step), b.max(c.us_per_step))
    });
    let mut chart = ChartBuilder::on(root)
        .caption(
            "chain cost per step (dt 1/60, 4 substeps, ratio 1, single thread)",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (8.0..n1 * 1.3).log_scale(),
            ((y0 / 2.0).max(0.1)..y1 * 3.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("links N")
        .y_desc("us per step")
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    for method in [
        Method::Lagrange,
        Method::Penalty(1e6),
        Method::Impulse,
        Method::Multibody,
        Method::RapierAlone,
        PEERS[0],
    ] {
        let pts: Vec<(f64, f64)> = costs
            .iter()
            .filter(|c| c.method == method)
            .map(|c| (c.n as f64, c.us_per_step))
            .collect();
        if pts.is_empty() {
            continue;
        }
        let c = method.color();
        // The legend gives each method's measured cost exponent (no guide lines to label).
        let label = match cost_exponent(&pts) {
            Some(p) => format!("{} (~N^{p:.2})", method.name()),
            None => method.name(),
        };
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(3)));
        chart.draw_series(pts.iter().map(|p| Circle::new(*p, 4, c.filled())))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()?;
    Ok(())
}

/// One grid panel: columns `xs` (labels), rows `ys` (labels, bottom up), each cell a colour and
/// a label.
pub(crate) fn draw_grid<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    caption: &str,
    [x_desc, y_desc]: [&str; 2],
    xs: &[String],
    ys: &[String],
    cell: impl Fn(usize, usize) -> Option<(RGBColor, String)>,
    font: u32,
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let (nx, ny) = (xs.len() as i32, ys.len() as i32);
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..nx as f64, 0f64..ny as f64)?;
    let label = |v: f64, names: &[String]| {
        let i = (v - 0.5).round();
        if (v - 0.5 - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < names.len() {
            names[i as usize].clone()
        } else {
            String::new()
        }
    };
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(nx as usize * 2 + 1)
        .y_labels(ny as usize * 2 + 1)
        .x_label_formatter(&|x| label(*x, xs))
        .y_label_formatter(&|y| label(*y, ys))
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 12))
        .draw()?;
    for i in 0..xs.len() {
        for j in 0..ys.len() {
            let (color, text) = cell(i, j).unwrap_or((RGBColor(240, 240, 240), "n/a".to_string()));
            let (x, y) = (i as f64, j as f64);
            chart.draw_series(std::iter::once(Rectangle::new(
                [(x + 0.03, y + 0.03), (x + 0.97, y + 0.97)],
                color.filled(),
            )))?;
            chart.draw_series(std::iter::once(Text::new(
                text,
                (x + 0.08, y + 0.62),
                ("sans-serif", font).into_font(),
            )))?;
        }
    }
    Ok(())
}

pub(crate) fn map_label(c: &MapCell) -> String {
    match c.class {
        "blew up" => "blew up".into(),
        "branch switch" => "branch".into(),
        "gap" => format!("gap {:.0e}", c.gap),
        "skipped" => "skipped".into(),
        _ => format!("{:.0e}", c.traj),
    }
}

pub(crate) const MAP_LEGEND: &str = "green <= 1e-3 m, light green <= 1e-1 m, orange > 1e-1 m, brown joint gap > 0.1 m (stopped there), violet branch switch, red blew up, grey n/a";

/// Draws a map's title (at `size` points) and the class legend on a 50-pixel band at the top of
/// `root`; returns the area below for the grid.
pub(crate) fn map_header<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    size: u32,
) -> DynResult<DrawingArea<DB, Shift>>
where
    DB::ErrorType: 'static,
{
    let (top, body) = root.split_vertically(50);
    top.draw(&Text::new(title, (10, 8), ("sans-serif", size).into_font()))?;
    top.draw(&Text::new(
        MAP_LEGEND,
        (10, 28),
        ("sans-serif", 12).into_font(),
    ))?;
    Ok(body)
}

pub(crate) fn draw_penalty<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    cfg: &Config,
    cells: &[MapCell],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let title = format!(
        "penalty pendulum (A01, 90 deg, {} s, 1 substep): stiffness x dt, max bob error vs exact",
        cfg.penalty_secs
    );
    let body = map_header(root, &title, 15)?;
    let xs: Vec<String> = cfg.penalty_rates.iter().map(|r| format!("1/{r}")).collect();
    let rows: Vec<f64> = cfg
        .penalty_ks
        .iter()
        .copied()
        .chain([f64::INFINITY])
        .collect();
    let ys: Vec<String> = rows
        .iter()
        .map(|k| {
            if k.is_finite() {
                format!("k {k:.0e}")
            } else {
                "lagrange".into()
            }
        })
        .collect();
    draw_grid(
        &body,
        "k (N/m, N m/rad) against dt (s)",
        ["dt (s)", "penalty stiffness k (N/m, N m/rad)"],
        &xs,
        &ys,
        |i, j| {
            let dt = 1.0 / cfg.penalty_rates[i] as f64;
            cells
                .iter()
                .find(|c| c.row == rows[j] && (c.dt - dt).abs() < 1e-12)
                .map(|c| (class_color(c.class), map_label(c)))
        },
        13,
    )
}

pub(crate) fn draw_singular<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    cfg: &Config,
    cells: &[MapCell],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let title = format!(
        "parallelogram four-bar (A02) released at rest delta above its singular pose, {} s, 1 substep: delta x dt, max crank-tip error vs exact",
        cfg.singular_secs
    );
    let body = map_header(root, &title, 14)?;
    let xs: Vec<String> = cfg
        .singular_rates
        .iter()
        .map(|r| format!("1/{r}"))
        .collect();
    let ys: Vec<String> = cfg
        .singular_deltas
        .iter()
        .map(|d| format!("{d:.0e}"))
        .collect();
    for (panel, method) in body.split_evenly(METHOD_GRID).iter().zip(METHODS) {
        draw_grid(
            panel,
            &method.name(),
            ["dt (s)", "start above the singular pose (rad)"],
            &xs,
            &ys,
            |i, j| {
                let dt = 1.0 / cfg.singular_rates[i] as f64;
                cells
                    .iter()
                    .find(|c| {
                        c.method == method
                            && c.row == cfg.singular_deltas[j]
                            && (c.dt - dt).abs() < 1e-12
                    })
                    .map(|c| (class_color(c.class), map_label(c)))
            },
            10,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The observed order's fit: a fourth-order sequence (each halved `h` divides the error by
    //! 16) gives 4 whatever tail of round-off follows its best point, and a method that stops
    //! converging above the floor keeps every point of its plateau.

    use super::observed_order;

    /// `(h, e)` for `h = 1/30 .. 1/7680` (`k` = 0 .. 8 halvings) with `e = f(k)`.
    fn halvings(f: impl Fn(usize) -> f64) -> Vec<(f64, f64)> {
        let mut pts: Vec<(f64, f64)> = (0..9)
            .map(|k| (1.0 / (30.0 * (1u32 << k) as f64), f(k)))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        pts
    }

    #[test]
    fn a_round_off_tail_past_the_best_error_is_left_out() {
        // The conical pendulum's fourth order in the 2026-11-27 study: 1.1e-5 m at 1/30 s, 16x
        // less per halving down to 1/1920 s (6.6e-13 m there in this sequence, 4.0e-13 in the
        // study), then 5.7e-10 and 1.7e-9 m at 1/3840 and 1/7680 s. The points above the 1e-9 m floor are the four coarsest and
        // the last; without the last the fit is exactly 4 (pure powers of 16), and with it
        // the slope was 1.41. 1e-9 of tolerance: the fit's own round-off.
        let tail = [5.7e-10, 1.7e-9];
        let pts = halvings(|k| {
            if k < 7 {
                1.1e-5 / 16f64.powi(k as i32)
            } else {
                tail[k - 7]
            }
        });
        let p = observed_order(&pts, 1e-9);
        assert!((p - 4.0).abs() < 1e-9, "order {p}");
    }

    #[test]
    fn a_plateau_above_the_floor_keeps_its_points() {
        // A soft penalty: first order down to 1/240 s, then stuck at its elastic gap of
        // 1e-2 m with a small wobble (the best point at 1/480 s). Its best error is above the
        // floor, so every point counts and the fit is well below 1 (a least-squares slope of
        // 1, 1, 1, 0, ... over eight intervals); dropping the points finer than the best one
        // would leave a fit of the first-order stretch and the best point alone (0.80).
        let pts = halvings(|k| match k {
            0..=3 => 8e-2 / 2f64.powi(k as i32),
            4 => 0.99e-2,
            _ => 1e-2,
        });
        let p = observed_order(&pts, 1e-9);
        assert!(p > 0.0 && p < 0.7, "order {p}");
    }
}
