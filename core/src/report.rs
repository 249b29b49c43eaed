//! Stage 7: reports for people and pipelines — text, JSON and JUnit XML.
//!
//! `validate` produces one `AssetReport` per asset with one `Check` per check name, so a JUnit
//! consumer shows one test case per asset × check.

use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    Pass,
    /// Worth knowing, not a failure (e.g. creases that repair fixes on bake).
    Warn,
    Fail,
    /// Not run because an earlier check failed (e.g. the mesh could not be read).
    Skipped,
}

#[derive(Clone, Debug, Serialize)]
pub struct Check {
    pub name: &'static str,
    pub status: Status,
    pub message: String,
    /// Faces the check names (indices into the file's triangles, after triangulation).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub faces: Vec<u32>,
    /// Seam edges the check names, as the pair of faces on their two sides (same indices as
    /// `faces`), worst first (`seam-jump`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub seam_edges: Vec<[u32; 2]>,
}

impl Check {
    pub fn pass(name: &'static str, message: impl Into<String>) -> Self {
        Check {
            name,
            status: Status::Pass,
            message: message.into(),
            faces: vec![],
            seam_edges: vec![],
        }
    }
    pub fn warn(name: &'static str, message: impl Into<String>) -> Self {
        Check {
            name,
            status: Status::Warn,
            message: message.into(),
            faces: vec![],
            seam_edges: vec![],
        }
    }
    pub fn fail(name: &'static str, message: impl Into<String>) -> Self {
        Check {
            name,
            status: Status::Fail,
            message: message.into(),
            faces: vec![],
            seam_edges: vec![],
        }
    }
    pub fn skipped(name: &'static str, why: impl Into<String>) -> Self {
        Check {
            name,
            status: Status::Skipped,
            message: why.into(),
            faces: vec![],
            seam_edges: vec![],
        }
    }
    pub fn with_faces(mut self, faces: Vec<u32>) -> Self {
        self.faces = faces;
        self
    }
    pub fn with_seam_edges(mut self, edges: Vec<[u32; 2]>) -> Self {
        self.seam_edges = edges;
        self
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct AssetReport {
    pub asset: String,
    pub checks: Vec<Check>,
}

impl AssetReport {
    pub fn failed(&self) -> bool {
        self.checks.iter().any(|c| c.status == Status::Fail)
    }
}

/// Human-readable report: one line per non-passing check, a summary line per asset.
pub fn to_text(reports: &[AssetReport]) -> String {
    let mut s = String::new();
    for r in reports {
        let fails = r.checks.iter().filter(|c| c.status == Status::Fail).count();
        let warns = r.checks.iter().filter(|c| c.status == Status::Warn).count();
        let verdict = if fails > 0 { "FAIL" } else { "ok" };
        s.push_str(&format!(
            "{verdict:4} {} ({} checks, {fails} failed, {warns} warnings)\n",
            r.asset,
            r.checks.len()
        ));
        for c in r.checks.iter().filter(|c| c.status != Status::Pass) {
            let tag = match c.status {
                Status::Fail => "error",
                Status::Warn => "warning",
                Status::Skipped => "skipped",
                Status::Pass => "ok",
            };
            s.push_str(&format!("  {tag}: {}: {}\n", c.name, c.message));
            if !c.faces.is_empty() {
                let shown: Vec<String> = c.faces.iter().take(20).map(|f| f.to_string()).collect();
                let more = if c.faces.len() > 20 {
                    format!(" … ({} in all)", c.faces.len())
                } else {
                    String::new()
                };
                s.push_str(&format!("    faces: {}{more}\n", shown.join(", ")));
            }
        }
    }
    let failed = reports.iter().filter(|r| r.failed()).count();
    s.push_str(&format!(
        "{} assets checked, {failed} with problems\n",
        reports.len()
    ));
    s
}

pub fn to_json(reports: &[AssetReport]) -> String {
    let failed = reports.iter().filter(|r| r.failed()).count();
    serde_json::to_string_pretty(&serde_json::json!({
        "assets": reports,
        "summary": {"assets": reports.len(), "failed": failed},
    }))
    .expect("report serialises")
}

fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // XML 1.0 forbids most control characters even escaped.
            c if (c as u32) < 0x20 && !matches!(c, '\n' | '\r' | '\t') => out.push('?'),
            c => out.push(c),
        }
    }
    out
}

/// JUnit XML (the Ant/Jenkins schema): one `<testsuite>` per asset, one `<testcase>` per check.
pub fn to_junit(reports: &[AssetReport]) -> String {
    let count = |r: &AssetReport, st: Status| r.checks.iter().filter(|c| c.status == st).count();
    let total: usize = reports.iter().map(|r| r.checks.len()).sum();
    let failures: usize = reports.iter().map(|r| count(r, Status::Fail)).sum();
    let skipped: usize = reports.iter().map(|r| count(r, Status::Skipped)).sum();
    let mut s = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    s.push_str(&format!(
        "<testsuites name=\"prismbake validate\" tests=\"{total}\" failures=\"{failures}\" errors=\"0\" skipped=\"{skipped}\">\n"
    ));
    for r in reports {
        let asset = xml_escape(&r.asset);
        s.push_str(&format!(
            "  <testsuite name=\"{asset}\" tests=\"{}\" failures=\"{}\" errors=\"0\" skipped=\"{}\">\n",
            r.checks.len(),
            count(r, Status::Fail),
            count(r, Status::Skipped)
        ));
        for c in &r.checks {
            let msg = xml_escape(&c.message);
            s.push_str(&format!(
                "    <testcase classname=\"{asset}\" name=\"{}\"",
                c.name
            ));
            let faces = if c.faces.is_empty() {
                String::new()
            } else {
                format!(
                    "\nfaces: {}",
                    c.faces
                        .iter()
                        .map(|f| f.to_string())
                        .collect::<Vec<_>>()
                        .join(" ")
                )
            };
            match c.status {
                Status::Pass => s.push_str(" />\n"),
                Status::Warn => s.push_str(&format!(">\n      <system-out>warning: {msg}{}</system-out>\n    </testcase>\n", xml_escape(&faces))),
                Status::Fail => s.push_str(&format!(
                    ">\n      <failure message=\"{msg}\" type=\"{}\">{msg}{}</failure>\n    </testcase>\n",
                    c.name,
                    xml_escape(&faces)
                )),
                Status::Skipped => s.push_str(&format!(">\n      <skipped message=\"{msg}\" />\n    </testcase>\n")),
            }
        }
        s.push_str("  </testsuite>\n");
    }
    s.push_str("</testsuites>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Vec<AssetReport> {
        vec![AssetReport {
            asset: "a<b>&\"c\".glb".into(),
            checks: vec![
                Check::pass("uvs", "ok"),
                Check::fail("inverted-normals", "2 corners <bad>").with_faces(vec![3, 4]),
                Check::warn("sharp-creases", "fixed"),
                Check::skipped("map", "no map"),
            ],
        }]
    }

    #[test]
    fn junit_counts_and_escapes() {
        let x = to_junit(&sample());
        assert!(x.contains("tests=\"4\" failures=\"1\" errors=\"0\" skipped=\"1\""));
        assert!(x.contains("a&lt;b&gt;&amp;&quot;c&quot;.glb"));
        assert!(x.contains("<failure message=\"2 corners &lt;bad&gt;\""));
        assert!(!x.contains("<bad>"));
    }

    #[test]
    fn json_is_valid_and_text_names_faces() {
        let v: serde_json::Value = serde_json::from_str(&to_json(&sample())).unwrap();
        assert_eq!(v["summary"]["failed"], 1);
        assert_eq!(v["assets"][0]["checks"][1]["faces"][1], 4);
        let t = to_text(&sample());
        assert!(t.contains("error: inverted-normals"));
        assert!(t.contains("faces: 3, 4"));
    }
}
