//! How deep an XML text's elements nest, found without recursion: the XML
//! parser (`roxmltree`) recurses once per level, so a file nested tens of
//! thousands deep would overflow the stack before any check could run.

/// The 1-based line and the name of the element where the nesting first
/// goes deeper than `limit`, or `None`. A scan, not a parser: comments, CDATA, processing
/// instructions, declarations and quoted attribute values are skipped;
/// malformed XML is left to the parser.
pub(super) fn too_deep(text: &str, limit: usize) -> Option<(usize, &str)> {
    let bytes = text.as_bytes();
    let (mut at, mut depth) = (0, 0usize);
    let skip_past = |from: usize, end: &str| {
        text[from..]
            .find(end)
            .map_or(bytes.len(), |k| from + k + end.len())
    };
    while let Some(k) = text[at..].find('<') {
        let start = at + k;
        let rest = &text[start..];
        at = if rest.starts_with("<!--") {
            skip_past(start, "-->")
        } else if rest.starts_with("<![CDATA[") {
            skip_past(start, "]]>")
        } else if rest.starts_with("<?") {
            skip_past(start, "?>")
        } else if rest.starts_with("<!") || rest.starts_with("</") {
            depth = depth.saturating_sub(usize::from(rest.starts_with("</")));
            skip_past(start, ">")
        } else {
            let end = tag_end(bytes, start);
            if bytes[..end].ends_with(b"/>") {
                end
            } else {
                depth += 1;
                if depth > limit {
                    let line = 1 + bytes[..start].iter().filter(|&&b| b == b'\n').count();
                    let name = rest[1..]
                        .split(|c: char| c.is_whitespace() || c == '>' || c == '/')
                        .next()
                        .unwrap_or("");
                    return Some((line, name));
                }
                end
            }
        };
    }
    None
}

/// The index just past the `>` closing the start tag at `start`, skipping
/// quoted attribute values (which may hold `>`).
fn tag_end(bytes: &[u8], start: usize) -> usize {
    let mut quote = None;
    for (i, &b) in bytes.iter().enumerate().skip(start + 1) {
        match (quote, b) {
            (None, b'"' | b'\'') => quote = Some(b),
            (Some(q), _) if b == q => quote = None,
            (None, b'>') => return i + 1,
            _ => {}
        }
    }
    bytes.len()
}

#[cfg(test)]
mod tests {
    use super::too_deep;

    #[test]
    fn counts_nesting_and_skips_what_is_not_an_element() {
        let text =
            "<?xml version=\"1.0\"?>\n<a>\n<b x=\"1>2\"/><!-- <c><c><c> -->\n<c><d/></c>\n</a>";
        assert_eq!(too_deep(text, 2), None);
        assert_eq!(too_deep(text, 1), Some((4, "c")));
        let deep = format!("{}{}", "<b>".repeat(100_000), "</b>".repeat(100_000));
        assert_eq!(too_deep(&deep, 256), Some((1, "b")));
        assert_eq!(too_deep("<![CDATA[<a><a>]]><a/>", 0), None);
    }
}
