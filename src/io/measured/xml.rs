//! A small XML reader for X3P's `main.xml`: elements (namespace prefixes dropped,
//! attributes skipped), their text, and their children. It skips the XML declaration,
//! processing instructions, comments and a DOCTYPE, reads CDATA, decodes the five named
//! entities and character references, and checks that tags nest. Nothing more: no
//! namespaces resolution, no DTDs, no validation.

#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Element {
    /// Local name (`p:ISO5436_2` → `ISO5436_2`).
    pub name: String,
    /// The element's own text (not its children's), entities decoded.
    pub text: String,
    pub children: Vec<Element>,
}

impl Element {
    pub(super) fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }

    /// The element at a path of child names, e.g. `["Record1", "FeatureType"]`.
    pub(super) fn at(&self, path: &[&str]) -> Option<&Element> {
        path.iter().try_fold(self, |e, name| e.child(name))
    }

    /// Trimmed text of the element at `path`.
    pub(super) fn text_at(&self, path: &[&str]) -> Option<&str> {
        self.at(path).map(|e| e.text.trim())
    }
}

/// Deeper documents are refused (X3P needs 4 levels).
const MAX_DEPTH: usize = 64;

fn local_name(qualified: &str) -> &str {
    qualified.rsplit(':').next().unwrap_or(qualified)
}

/// Parses `doc` into its root element; errors say what is wrong and at which line.
pub(super) fn parse(doc: &str) -> Result<Element, String> {
    let line_of = |at: usize| doc[..at].matches('\n').count() + 1;
    let fail = |at: usize, what: &str| format!("main.xml line {}: {what}", line_of(at));
    // Open elements with their qualified names; finished root.
    let mut stack: Vec<(String, Element)> = Vec::new();
    let mut root: Option<Element> = None;
    let mut at = 0;
    while at < doc.len() {
        let rest = &doc[at..];
        if !rest.starts_with('<') {
            let end = rest.find('<').map_or(doc.len(), |p| at + p);
            let text = &doc[at..end];
            match stack.last_mut() {
                Some((_, e)) => e.text += &decode_entities(text).map_err(|w| fail(at, &w))?,
                None if !text.trim().is_empty() => {
                    return Err(fail(at, "text outside the root element"));
                }
                None => {}
            }
            at = end;
            continue;
        }
        let skip_to = |end: &str, what: &str| match rest.find(end) {
            Some(p) => Ok(at + p + end.len()),
            None => Err(format!(
                "main.xml line {}: unterminated {what}",
                line_of(at)
            )),
        };
        if rest.starts_with("<?") {
            at = skip_to("?>", "processing instruction")?;
        } else if rest.starts_with("<!--") {
            at = skip_to("-->", "comment")?;
        } else if let Some(cdata) = rest.strip_prefix("<![CDATA[") {
            let Some(p) = cdata.find("]]>") else {
                return Err(fail(at, "unterminated CDATA section"));
            };
            if let Some((_, e)) = stack.last_mut() {
                e.text += &cdata[..p];
            }
            at += "<![CDATA[".len() + p + 3;
        } else if rest.starts_with("<!") {
            if rest.contains('[') && rest.find('[') < rest.find('>') {
                return Err(fail(at, "DOCTYPE with an internal subset is not supported"));
            }
            at = skip_to(">", "declaration")?;
        } else if let Some(close) = rest.strip_prefix("</") {
            let Some(p) = close.find('>') else {
                return Err(fail(at, "unterminated end tag"));
            };
            let name = close[..p].trim();
            let Some((open, element)) = stack.pop() else {
                return Err(fail(at, &format!("end tag </{name}> without a start tag")));
            };
            if open != name {
                return Err(fail(at, &format!("</{name}> closes <{open}>")));
            }
            match stack.last_mut() {
                Some((_, parent)) => parent.children.push(element),
                None => root = Some(element),
            }
            at += 2 + p + 1;
        } else {
            let end = tag_end(rest)
                .ok_or_else(|| format!("main.xml line {}: unterminated start tag", line_of(at)))?;
            let tag = &rest[1..end];
            let self_closing = tag.ends_with('/');
            let tag = tag.trim_end_matches('/');
            let name = tag.split(|c: char| c.is_whitespace()).next().unwrap_or("");
            if name.is_empty() {
                return Err(fail(at, "a tag without a name"));
            }
            if root.is_some() {
                return Err(fail(at, &format!("<{name}> after the root element")));
            }
            if stack.len() >= MAX_DEPTH {
                return Err(fail(at, "elements nested too deeply"));
            }
            let element = Element {
                name: local_name(name).to_string(),
                ..Default::default()
            };
            if self_closing {
                match stack.last_mut() {
                    Some((_, parent)) => parent.children.push(element),
                    None => root = Some(element),
                }
            } else {
                stack.push((name.to_string(), element));
            }
            at += end + 1;
        }
    }
    if let Some((open, _)) = stack.last() {
        return Err(format!("main.xml: <{open}> is never closed"));
    }
    root.ok_or_else(|| "main.xml has no root element".to_string())
}

/// Index of the `>` that ends the tag starting at `tag[0] == '<'`, outside quotes.
fn tag_end(tag: &str) -> Option<usize> {
    let mut quote: Option<char> = None;
    for (i, c) in tag.char_indices().skip(1) {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, '"' | '\'') => quote = Some(c),
            (None, '>') => return Some(i),
            (None, '<') => return None,
            _ => {}
        }
    }
    None
}

fn decode_entities(text: &str) -> Result<String, String> {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(p) = rest.find('&') {
        out += &rest[..p];
        let after = &rest[p + 1..];
        let Some(semi) = after.find(';') else {
            return Err("`&` without `;`".into());
        };
        let name = &after[..semi];
        let ch = match name {
            "lt" => Some('<'),
            "gt" => Some('>'),
            "amp" => Some('&'),
            "quot" => Some('"'),
            "apos" => Some('\''),
            _ => match name.strip_prefix("#x").or_else(|| name.strip_prefix("#X")) {
                Some(hex) => u32::from_str_radix(hex, 16).ok().and_then(char::from_u32),
                None => name
                    .strip_prefix('#')
                    .and_then(|d| d.parse().ok())
                    .and_then(char::from_u32),
            },
        };
        let Some(ch) = ch else {
            return Err(format!("unknown entity `&{name};`"));
        };
        out.push(ch);
        rest = &after[semi + 1..];
    }
    out += rest;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_elements_text_and_skips_the_rest() {
        let doc = r#"<?xml version="1.0" encoding="UTF-8"?>
<!-- a comment <Record1> that is not one -->
<!DOCTYPE p:ISO5436_2>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2" note='a > b'>
  <Record1>
    <FeatureType> SUR </FeatureType>
    <p:Axes><CX><Increment>1.5e-6</Increment></CX></p:Axes>
  </Record1>
  <Record3><DataList><Datum>1</Datum><Datum/><Datum>&lt;3&#x41;&#66;</Datum>
  <Datum><![CDATA[x<y]]></Datum></DataList></Record3>
</p:ISO5436_2>
"#;
        let root = parse(doc).unwrap();
        assert_eq!(root.name, "ISO5436_2");
        assert_eq!(root.text_at(&["Record1", "FeatureType"]), Some("SUR"));
        let inc = root.text_at(&["Record1", "Axes", "CX", "Increment"]);
        assert_eq!(inc, Some("1.5e-6"));
        let data: Vec<&str> = root
            .at(&["Record3", "DataList"])
            .unwrap()
            .children
            .iter()
            .map(|d| d.text.as_str())
            .collect();
        assert_eq!(data, ["1", "", "<3AB", "x<y"]);
        assert_eq!(root.at(&["Record2"]), None);
    }

    #[test]
    fn malformed_documents_are_errors() {
        let cases = [
            ("<a><b></a>", "closes"),
            ("<a>", "never closed"),
            ("", "no root"),
            ("<a></a><b/>", "after the root"),
            ("<a>&bogus;</a>", "unknown entity"),
            ("<a><!-- open", "unterminated comment"),
            ("text<a/>", "outside the root"),
            ("<a\n  x='1'", "line 1: unterminated start tag"),
            ("<a>\n</b>", "line 2"),
        ];
        for (doc, why) in cases {
            let e = parse(doc).unwrap_err();
            assert!(e.contains(why), "{doc:?}: {e}");
        }
        let deep = "<a>".repeat(100) + &"</a>".repeat(100);
        assert!(parse(&deep).unwrap_err().contains("too deeply"));
    }
}
