//! The grid-forming qualification suite (`cargo xtask qualify`'s runs, a subset in debug builds): each cell's verdict from its measurements against its bound, passing but for the open cases listed here (each must still fail, so that a fix shows), and the HTML report rendered in headless Chromium with every figure drawn and no console error.

use dvpp_studies::qualify::{self, judge, Job, Row, Subject, Test};
use dvpp_studies::ride_through::Control;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The cells that fail today (test id, subject, control short name), each for a limit of the
/// design named in docs/qualification.md ("Why cells fail"): each must still fail.
const OPEN: &[(&str, &str, &str)] = &[
    // The energy-based inertia below ERCOT's 2.5 s: T_des's 2.78 s and the response's lag.
    ("rocof1", "wind", "A"),
    ("rocof1", "wind", "B"),
    ("rocof1", "PV", "A"),
    ("rocof1", "PV", "B"),
    ("rocof1", "BESS", "A"),
    ("rocof1", "BESS", "B"),
    ("rocof1", "DVPP", "A"),
    ("rocof1", "DVPP", "B"),
    // Option B's current-limited mode (the ride-through study's OPEN_B at SCR 3).
    ("jump25down", "DVPP", "B"),
    ("rocof5up", "BESS", "B"),
    ("rocof5up", "DVPP", "B"),
    ("rocof5down", "wind", "B"),
    ("rocof5down", "PV", "B"),
    ("rocof5down", "BESS", "B"),
    ("rocof5down", "DVPP", "B"),
    // The DVPP at I_max through -5 Hz/s (the ride-through study's OPEN_A at SCR 3).
    ("rocof5down", "DVPP", "A"),
    // A grid-following unit alone at +5 Hz/s (docs/emt.md §9): wind and PV driven to zero
    // active current, the BESS to absorbing it (a negative conductance at the capacitor's
    // resonance on SCR 3).
    ("rocof5up", "wind", "GFL"),
    ("rocof5up", "PV", "GFL"),
    ("rocof5up", "BESS", "GFL"),
];

/// The workspace root the bundled systems are under (`DVPP_DIST` is `ROOT/dist/default`).
fn root() -> PathBuf {
    let dist = dvpp_e2e::dist();
    dist.parent()
        .and_then(|d| d.parent())
        .expect("DVPP_DIST is ROOT/dist/default")
        .to_path_buf()
}

/// The runs of the test: in release builds every run of the suite; in debug builds (a few
/// minutes on two cores) each test on one unit alone with option A and grid-following, and on
/// the DVPP with option A and B.
fn subset() -> Vec<Job> {
    let all = qualify::jobs();
    if !cfg!(debug_assertions) {
        return all;
    }
    all.into_iter()
        .filter(|j| {
            let unit = match j.test {
                Test::Island { .. } | Test::Rocof1 | Test::VoltageStep => Subject::Bess,
                Test::Dip(_) | Test::Unbalanced(_) | Test::Damping => Subject::Pv,
                _ => Subject::Wind,
            };
            (j.subject == unit && j.control != Control::FormingB)
                || (j.subject == Subject::Dvpp && j.control != Control::Following)
        })
        .collect()
}

fn rows() -> &'static [Row] {
    static ROWS: std::sync::OnceLock<Vec<Row>> = std::sync::OnceLock::new();
    ROWS.get_or_init(|| {
        let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
        qualify::run_all(&root(), subset(), workers).unwrap_or_else(|e| panic!("{e}"))
    })
}

fn is_open(job: &Job) -> bool {
    OPEN.iter().any(|&(test, subject, control)| {
        job.test.id() == test
            && job.subject.name() == subject
            && qualify::control_short(job.control) == control
    })
}

/// Every cell passes its bound from its measurements but the open ones, which still fail; the
/// failures with the measured figure beside the bound.
#[test]
fn every_cell_meets_its_bound_but_the_open_cases() {
    let rows = rows();
    let mut failed = Vec::new();
    for r in rows {
        let cell = judge(r);
        let open = is_open(&r.job);
        if !cell.pass && !open {
            failed.push(format!(
                "{}: {} against {}: {}",
                r.job.name(),
                cell.figure,
                cell.bound,
                cell.why
            ));
        } else if cell.pass && open {
            failed.push(format!(
                "{}: passes now ({} against {}): take it off the open cases here and in docs/qualification.md",
                r.job.name(),
                cell.figure,
                cell.bound
            ));
        }
        if r.error.is_none() {
            // The measurements the verdicts come from are finite and within their ranges.
            assert!(
                r.p0.is_finite() && r.v0 > 0.5,
                "{}: p0 {}, v0 {}",
                r.job.name(),
                r.p0,
                r.v0
            );
            assert!(
                r.i_peak.iter().all(|i| i.is_finite() && *i > 0.0),
                "{}",
                r.job.name()
            );
        }
    }
    assert!(
        failed.is_empty(),
        "{} of {} cells:\n{}",
        failed.len(),
        rows.len(),
        failed.join("\n")
    );
}

/// The matrix has a cell for every run, beginning with its verdict, and `n/a` where a test does
/// not apply.
#[test]
fn the_matrix_has_every_verdict() {
    let rows = rows();
    let matrix = qualify::matrix(rows);
    for r in rows {
        let cell = judge(r);
        assert!(
            matrix.contains(&format!(" {} |", cell.text())),
            "{}: '{}' not in\n{matrix}",
            r.job.name(),
            cell.text()
        );
    }
    assert!(matrix.contains(" n/a |"), "{matrix}");
}

/// The expected responses the envelopes are judged against follow from `T_des` alone: the
/// inertia a run without any deviation from `T_des` would show is `T_des`'s `H/2`.
#[test]
fn the_inertia_estimate_returns_t_des_for_t_des_energy() {
    let job = Job {
        subject: Subject::Bess,
        control: Control::FormingA,
        test: Test::Rocof1,
    };
    let mut row = qualify::measure(job, Err("none".into()));
    row.energy = qualify::expected_energy();
    let h = qualify::inertia(&row);
    assert!((h - qualify::TDES_H / 2.0).abs() < 1e-12, "{h}");
}

fn chromium() -> Option<PathBuf> {
    ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file())
}

/// A script appended to the page for the test: for each figure, its drawn size and the number
/// of lines in it, written into the page (read back from the dumped DOM); page errors go to the
/// console.
const CHECK: &str = r#"<script>
window.addEventListener('error', e => console.error('page error: ' + e.message));
const out = [];
document.querySelectorAll('figure > svg').forEach((s, k) => {
  const b = s.getBoundingClientRect();
  out.push(k + ':' + Math.round(b.width) + 'x' + Math.round(b.height) + ':' + s.querySelectorAll('polyline, path').length);
});
const pre = document.createElement('pre');
pre.id = 'render-check';
pre.textContent = out.join(' ');
document.body.appendChild(pre);
</script>"#;

fn render(page: &Path) -> (String, String) {
    let browser = match chromium() {
        Some(b) => b,
        None if std::env::var("DVPP_REQUIRE_CHROMIUM").is_ok_and(|v| v == "1") => {
            panic!("chromium is not installed (cargo xtask test installs Debian's chromium)")
        }
        None => {
            eprintln!("skipped: no chromium (apt-get install chromium, or cargo xtask test)");
            return (String::new(), String::new());
        }
    };
    let profile = page.parent().expect("a directory").join("profile");
    let out = Command::new(browser)
        .args([
            "--headless",
            "--disable-gpu",
            "--no-sandbox",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=5000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium runs");
    assert!(out.status.success(), "chromium: {out:?}");
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The report renders in a real browser: every figure drawn with its lines at a real size, and
/// no console message (an error of the page would be one).
#[test]
fn the_report_renders_every_figure_in_chromium() {
    let rows = rows();
    let html = qualify::html(rows, "test build", 0.0);
    // Self-contained: nothing loaded (the only URL is the SVG namespace).
    assert!(
        !html.contains("src=") && !html.contains("href=\"http"),
        "no network"
    );
    let figures = html.matches("<figure>").count();
    assert!(figures >= 10, "{figures} figures");
    let dir = std::env::temp_dir().join(format!("dvpp-qualify-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let page = dir.join("qualification.html");
    std::fs::write(&page, html.replace("</body>", &format!("{CHECK}\n</body>"))).unwrap();
    let (dom, log) = render(&page);
    if dom.is_empty() {
        return;
    }
    let console: Vec<&str> = log.lines().filter(|l| l.contains("CONSOLE")).collect();
    assert!(
        console.is_empty(),
        "console messages:\n{}",
        console.join("\n")
    );
    let check = dom
        .split("<pre id=\"render-check\">")
        .nth(1)
        .and_then(|r| r.split("</pre>").next())
        .unwrap_or_else(|| panic!("the check script did not run; stderr:\n{log}"));
    let drawn: Vec<&str> = check.split_whitespace().collect();
    assert_eq!(drawn.len(), figures, "{check}");
    for d in &drawn {
        let parts: Vec<&str> = d.split(':').collect();
        let (w, h) = parts[1].split_once('x').unwrap();
        let lines: usize = parts[2].parse().unwrap();
        assert!(
            w.parse::<f64>().unwrap() > 100.0 && h.parse::<f64>().unwrap() > 100.0 && lines > 0,
            "figure {d} (index:size:lines) is not drawn"
        );
    }
    println!("chromium rendered {} figures: {check}", drawn.len());
    let _ = std::fs::remove_dir_all(&dir);
}
