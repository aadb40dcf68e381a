//! Self-contained HTML reports: one page, images embedded as base64 data URIs, no server.

/// Base64 (RFC 4648, with padding).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                out.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
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
        }
    }
    s.push_str("</body>\n</html>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }

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
            ],
        );
        assert!(h.starts_with("<!DOCTYPE html>"));
        assert!(h.contains("<title>run &lt;1&gt;</title>"));
        assert!(h.contains("<td>a &amp; b</td><td class=\"pass\">PASS</td>"));
        assert!(h.contains("src=\"data:image/png;base64,AQID\""));
        assert!(h.trim_end().ends_with("</html>"));
    }
}
