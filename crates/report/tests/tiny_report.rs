//! Runs a tiny accuracy report end to end (three scenes, two steps, tiny budgets), writes it, and
//! checks that every table of the document has the rows its options ask for — counting every row
//! it checked, so a document whose tables went missing cannot pass — and that every SVG it wrote
//! is well-formed, keeps its legend outside the plot areas and has no overlapping point labels.

use furbake_formats::sections::keyframe_table::DisplacementEncoding;
use furbake_grass::PoseInterpolation;
use furbake_report::fur::{AccuracySettings, SceneId, chart_name, configurations};
use furbake_report::grass::GrassAccuracyOptions;
use furbake_report::svg::Rect;
use furbake_report::{AccuracyOptions, DOCUMENT_NAME, ReportPart, accuracy_document};
use furbake_sim::SolverKind;

/// The markdown's tables in order: (the heading above it, its data rows as cells).
fn tables(markdown: &str) -> Vec<(String, Vec<Vec<String>>)> {
    let mut out: Vec<(String, Vec<Vec<String>>)> = Vec::new();
    let mut heading = String::new();
    let mut in_table = false;
    for line in markdown.lines() {
        if line.starts_with('#') {
            heading = line.trim_start_matches('#').trim().to_owned();
            in_table = false;
        } else if let Some(row) = line.strip_prefix('|') {
            let cells: Vec<String> = row.trim_end_matches('|').split('|').map(|c| c.trim().to_owned()).collect();
            if !in_table {
                // The header row; the rule row follows and is skipped below.
                out.push((heading.clone(), Vec::new()));
                in_table = true;
            } else if !cells.iter().all(|c| c.trim_matches(|ch| ch == '-' || ch == ':').is_empty()) {
                out.last_mut().expect("a table was started").1.push(cells);
            }
        } else {
            in_table = false;
        }
    }
    out
}

/// A tiny XML well-formedness check: tags balance, attribute quotes pair up, text holds no raw
/// `<` and only the five XML entities. Returns the start tags as (name, raw attribute text).
fn parse_xml(xml: &str) -> Result<Vec<(String, String)>, String> {
    let mut stack: Vec<String> = Vec::new();
    let mut tags = Vec::new();
    let mut rest = xml;
    while let Some(open) = rest.find('<') {
        let text = &rest[..open];
        for (i, _) in text.match_indices('&') {
            let entity = &text[i..];
            if !["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"].iter().any(|e| entity.starts_with(e)) {
                return Err(format!("bad entity in text {text:?}"));
            }
        }
        let close = rest[open..].find('>').ok_or("an unclosed tag")? + open;
        let tag = &rest[open + 1..close];
        rest = &rest[close + 1..];
        if tag.starts_with('?') || tag.starts_with('!') {
            continue;
        }
        if !tag.matches('"').count().is_multiple_of(2) {
            return Err(format!("unpaired quote in <{tag}>"));
        }
        if let Some(name) = tag.strip_prefix('/') {
            let top = stack.pop().ok_or_else(|| format!("</{name}> closes nothing"))?;
            if top != name.trim() {
                return Err(format!("</{name}> closes <{top}>"));
            }
            continue;
        }
        let name: String = tag.chars().take_while(|c| !c.is_whitespace() && *c != '/').collect();
        if name.is_empty() {
            return Err(format!("a tag without a name: <{tag}>"));
        }
        tags.push((name.clone(), tag.to_owned()));
        if !tag.ends_with('/') {
            stack.push(name);
        }
    }
    if !rest.trim().is_empty() {
        return Err(format!("text after the root: {rest:?}"));
    }
    if let Some(open) = stack.pop() {
        return Err(format!("<{open}> is never closed"));
    }
    Ok(tags)
}

fn attr(tag: &str, name: &str) -> Option<f64> {
    let key = format!(" {name}=\"");
    let start = tag.find(&key)? + key.len();
    tag[start..].split('"').next()?.parse().ok()
}

fn rect_of(tag: &str) -> Rect {
    let get = |n| attr(tag, n).unwrap_or_else(|| panic!("{n} of {tag}"));
    Rect { x: get("x"), y: get("y"), w: get("width"), h: get("height") }
}

/// Checks one generated SVG; returns the number of point labels it has.
fn check_svg(name: &str, svg: &str) -> usize {
    let tags = parse_xml(svg).unwrap_or_else(|e| panic!("{name} is not well-formed: {e}"));
    assert_eq!(tags.first().map(|t| t.0.as_str()), Some("svg"), "{name}: the root is <svg>");
    let areas: Vec<Rect> =
        tags.iter().filter(|t| t.0 == "rect" && t.1.contains("class=\"plot-area\"")).map(|t| rect_of(&t.1)).collect();
    let legends: Vec<Rect> =
        tags.iter().filter(|t| t.0 == "rect" && t.1.contains("class=\"legend-box\"")).map(|t| rect_of(&t.1)).collect();
    assert!(!areas.is_empty(), "{name}: plot areas");
    assert_eq!(legends.len(), 1, "{name}: one legend");
    for l in &legends {
        for a in &areas {
            assert!(!l.overlaps(a), "{name}: legend {l:?} over plot area {a:?}");
        }
    }
    let labels: Vec<Rect> = tags
        .iter()
        .filter(|t| t.0 == "text" && t.1.contains("class=\"label\""))
        .map(|t| {
            let v: Vec<f64> =
                t.1.split("data-box=\"")
                    .nth(1)
                    .and_then(|r| r.split('"').next())
                    .unwrap_or("")
                    .split(' ')
                    .filter_map(|x| x.parse().ok())
                    .collect();
            assert_eq!(v.len(), 4, "{name}: a label box in {}", t.1);
            Rect { x: v[0], y: v[1], w: v[2], h: v[3] }
        })
        .collect();
    for (i, a) in labels.iter().enumerate() {
        assert!(areas.iter().any(|p| p.contains(a)), "{name}: label {a:?} outside every plot area");
        assert!(!legends.iter().any(|l| l.overlaps(a)), "{name}: label {a:?} under the legend");
        for b in &labels[i + 1..] {
            assert!(!a.overlaps(b), "{name}: labels {a:?} and {b:?} overlap");
        }
    }
    assert!(svg.contains("log scale"), "{name}: log axes are marked");
    assert!(!svg.contains("left out for lack of room"), "{name}: every point is labelled");
    labels.len()
}

#[test]
fn the_xml_checker_rejects_broken_svg() {
    assert!(parse_xml("<svg><g></svg>").is_err());
    assert!(parse_xml("<svg><text>a < b</text></svg>").is_err());
    assert!(parse_xml("<svg><text>a & b</text></svg>").is_err());
    assert!(parse_xml("<svg><rect x=\"1/></svg>").is_err());
    assert_eq!(parse_xml("<svg><rect x=\"1\"/><text>a &amp; b</text></svg>").map(|t| t.len()), Ok(3));
}

#[test]
fn a_tiny_report_has_every_table_with_the_expected_rows() {
    let scenes = vec![SceneId::GrassPatchPrisms, SceneId::StiffNet, SceneId::FoxSticks];
    let options = AccuracyOptions {
        fur: AccuracySettings {
            scenes: scenes.clone(),
            step_sizes_s: vec![1.0 / 30.0, 1.0 / 300.0],
            iterations: vec![1, 2],
            reference_dt_s: 1.0 / 1500.0,
            duration_s: 0.1,
            fox_duration_s: 0.02,
            repeats: 1,
            timing_sizes: vec![(200, 300), (400, 600)],
            timing_budget_s: 0.0,
            ..AccuracySettings::default()
        },
        grass: GrassAccuracyOptions {
            pose_counts: vec![12, 100],
            encodings: vec![DisplacementEncoding::F32, DisplacementEncoding::Snorm8],
            queries: 5,
            timing_repeats: 1,
            cluster_sizes_m: vec![1.0, 4.0],
            field_density_per_m2: 2.0,
        },
    };
    let mut parts = Vec::new();
    let doc = accuracy_document(&options, |p| parts.push(p)).expect("the tiny report runs");
    assert_eq!(parts, [ReportPart::Fur, ReportPart::Grass]);
    assert!(doc.markdown.starts_with("<!-- Generated by `make report`"));
    // Each table states scene, metric, reference, floor and machine.
    for word in ["Scene:", "Metric:", "Reference", "Floor", "Machine:"] {
        assert!(doc.markdown.matches(word).count() >= scenes.len(), "{word} is stated per table");
    }

    let configs = configurations(&options.fur.iterations);
    let steps = options.fur.step_sizes_s.len();
    let full_rows = configs.len() * 2 * steps;
    let found = tables(&doc.markdown);
    let mut rows_checked = 0;
    let mut t = found.iter();
    for scene in &scenes {
        let (front_heading, front) = t.next().expect("a Pareto table");
        let (full_heading, full) = t.next().expect("a full table");
        assert_eq!(front_heading, &format!("{} — Pareto front", scene.title()));
        assert_eq!(full_heading, &format!("{} — every configuration", scene.title()));
        assert_eq!(full.len(), full_rows, "{full_heading}");
        assert!(!front.is_empty() && front.len() <= full.len(), "{front_heading}");
        for row in front {
            assert_eq!(row.len(), 8);
            // Every front row is a measured configuration of the full table.
            assert!(full.iter().any(|f| f[..7] == row[..7]), "{row:?} is in the full table");
            rows_checked += 1;
        }
        // Every solver kind and iteration count appears, raw and default.
        for (kind, it) in &configs {
            let config = match it {
                Some(n) => format!("{} ×{n}", kind.name()),
                None => kind.name().to_owned(),
            };
            for mode in ["raw", "default"] {
                let n = full.iter().filter(|r| r[0] == config && r[1] == mode).count();
                assert_eq!(n, steps, "{full_heading}: {config} {mode}");
            }
        }
        for row in full {
            assert_eq!(row.len(), 8, "{full_heading}: {row:?}");
            assert!(row.iter().all(|c| !c.is_empty()), "{full_heading}: an empty cell in {row:?}");
            rows_checked += 1;
        }
    }
    let rest: Vec<_> = t.collect();
    let expected: [(&str, usize, usize); 4] = [
        ("Time per step", options.fur.timing_sizes.len(), 2 + SolverKind::ALL.len()),
        (
            "Pose error against the direct simulation",
            options.grass.pose_counts.len() * PoseInterpolation::ALL.len() * options.grass.encodings.len(),
            6,
        ),
        ("Quantisation", DisplacementEncoding::ALL.len(), 6),
        ("Per-blade force error by cluster size", options.grass.cluster_sizes_m.len() * 2, 7),
    ];
    assert_eq!(rest.len(), expected.len(), "tables: {:?}", rest.iter().map(|t| &t.0).collect::<Vec<_>>());
    for ((heading, rows), (want_heading, want_rows, want_cells)) in rest.into_iter().zip(expected) {
        assert!(heading.starts_with(want_heading), "{heading:?} is not {want_heading:?}");
        assert_eq!(rows.len(), want_rows, "{heading}: rows");
        for row in rows {
            assert_eq!(row.len(), want_cells, "{heading}: {row:?}");
            assert!(row.iter().all(|c| !c.is_empty()), "{heading}: an empty cell in {row:?}");
            rows_checked += 1;
        }
    }
    assert!(rows_checked >= 3 * full_rows + 3 + 2 + 12 + 5 + 4, "{rows_checked} rows");

    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = doc.write_into(&dir.path().join("docs")).expect("writes");
    assert_eq!(path, dir.path().join("docs").join(DOCUMENT_NAME));
    assert_eq!(std::fs::read_to_string(&path).expect("the document"), doc.markdown);
    // A chart per scene, the time chart and the grass chart.
    assert_eq!(doc.plots.len(), scenes.len() + 2);
    for scene in &scenes {
        assert!(doc.plots.iter().any(|p| p.0 == chart_name(*scene)), "{scene:?} has a chart");
    }
    let mut labels = 0;
    for (name, svg) in &doc.plots {
        let written = std::fs::read_to_string(dir.path().join("docs").join(name)).expect("a plot");
        assert_eq!(&written, svg);
        assert!(doc.markdown.contains(&format!("]({name})")), "the markdown links {name}");
        labels += check_svg(name, svg);
    }
    // Every measured point of the scene charts and the grass chart is labelled.
    assert!(labels >= scenes.len() * full_rows, "{labels} labels");
}
