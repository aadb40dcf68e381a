//! Self-contained HTML reports: one page, images embedded as base64 data URIs, no server.

/// Base64 (RFC 4648, with padding) of `bytes`.
pub fn base64(bytes: &[u8]) -> String {
    use base64::Engine;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// Escapes text for HTML.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A piece of a report.
#[derive(Clone, Debug)]
pub enum Block {
    /// A section heading.
    Heading(String),
    /// A paragraph.
    Text(String),
    /// A table: header and rows; a cell "PASS"/"FAIL" is coloured.
    Table(Vec<String>, Vec<Vec<String>>),
    /// A PNG image with a caption.
    Image(String, Vec<u8>),
    /// An SVG chart with a caption, inlined.
    Svg(String, String),
    /// Preformatted text (e.g. the case file).
    Pre(String),
}

/// The whole page.
pub fn html(title: &str, blocks: &[Block]) -> String {
    let mut s = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>\nbody{{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}}\ntable{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:4px 8px;text-align:left}}\nth{{background:#eee}}.pass{{background:#d4f7d4}}.fail{{background:#f7d4d4}}\nimg{{max-width:100%;border:1px solid #ddd;margin:0.5em 0}}figure{{margin:1em 0}}pre{{background:#f6f6f6;padding:1em;overflow-x:auto}}\n</style>\n</head>\n<body>\n<h1>{}</h1>\n",
        escape(title),
        escape(title)
    );
    for b in blocks {
        match b {
            Block::Heading(h) => s.push_str(&format!("<h2>{}</h2>\n", escape(h))),
            Block::Text(t) => s.push_str(&format!("<p>{}</p>\n", escape(t))),
            Block::Pre(t) => s.push_str(&format!("<pre>{}</pre>\n", escape(t))),
            Block::Table(head, rows) => {
                s.push_str("<table>\n<tr>");
                for h in head {
                    s.push_str(&format!("<th>{}</th>", escape(h)));
                }
                s.push_str("</tr>\n");
                for r in rows {
                    s.push_str("<tr>");
                    for c in r {
                        let class = match c.as_str() {
                            "PASS" => " class=\"pass\"",
                            "FAIL" => " class=\"fail\"",
                            _ => "",
                        };
                        s.push_str(&format!("<td{class}>{}</td>", escape(c)));
                    }
                    s.push_str("</tr>\n");
                }
                s.push_str("</table>\n");
            }
            Block::Image(caption, png) => s.push_str(&format!(
                "<figure><img alt=\"{}\" src=\"data:image/png;base64,{}\"><figcaption>{}</figcaption></figure>\n",
                escape(caption),
                base64(png),
                escape(caption)
            )),
            Block::Svg(caption, svg) => s.push_str(&format!(
                "<figure>{}<figcaption>{}</figcaption></figure>\n",
                svg.trim_start_matches("<?xml version=\"1.0\" encoding=\"UTF-8\"?>"),
                escape(caption)
            )),
        }
    }
    s.push_str("</body>\n</html>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_holds_tables_images_and_escaped_text() {
        let h = html(
            "run <1>",
            &[
                Block::Table(
                    vec!["check".into(), "result".into()],
                    vec![vec!["a & b".into(), "PASS".into()]],
                ),
                Block::Image("fig".into(), vec![1, 2, 3]),
                Block::Svg("chart".into(), "<svg width=\"1\"></svg>".into()),
            ],
        );
        assert!(h.starts_with("<!DOCTYPE html>"));
        assert!(h.contains("<title>run &lt;1&gt;</title>"));
        assert!(h.contains("<td>a &amp; b</td><td class=\"pass\">PASS</td>"));
        assert!(h.contains("src=\"data:image/png;base64,AQID\""));
        assert!(h.contains("<figure><svg width=\"1\"></svg><figcaption>chart</figcaption>"));
        assert!(h.trim_end().ends_with("</html>"));
    }
}
