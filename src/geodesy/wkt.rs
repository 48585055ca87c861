//! A WKT CRS as a plain tree of keywords and values (through the
//! `proj4wkt` crate's parser), for what its conversion to a PROJ string
//! does not keep: authority codes, the vertical part of a compound CRS, the
//! datum's name.

use proj4wkt::parser::{parse as parse_wkt, Attribute, Processor};

#[derive(Debug, Clone)]
pub struct Node {
    pub key: String,
    pub items: Vec<Item>,
}

#[derive(Debug, Clone)]
pub enum Item {
    Text(String),
    Number(String),
    Label(String),
    Node(Node),
}

struct TreeBuilder;

impl<'a> Processor<'a> for TreeBuilder {
    type Err = std::io::Error;
    type Output = Node;

    fn process<I>(&self, key: &'a str, _depth: usize, attrs: I) -> Result<Node, Self::Err>
    where
        I: Iterator<Item = Attribute<'a, Node>>,
    {
        let items = attrs
            .map(|a| match a {
                Attribute::Quoted(s) => Item::Text(s.to_string()),
                Attribute::Number(s) => Item::Number(s.to_string()),
                Attribute::Label(s) => Item::Label(s.to_string()),
                Attribute::Keyword(_, n) => Item::Node(n),
            })
            .collect();
        Ok(Node { key: key.to_ascii_uppercase(), items })
    }
}

/// The deepest nesting of brackets a CRS's WKT is read with. Real ones
/// nest six or seven deep (a compound CRS's projection's datum's
/// ellipsoid's unit…); the parser recurses once a level, so a text nested
/// tens of thousands deep would overflow the stack.
pub const MAX_DEPTH: usize = 64;

/// The tree of a WKT text, or why it is not WKT.
pub fn parse(text: &str) -> Result<Node, String> {
    let text = text.trim();
    check_shape(text)?;
    parse_wkt(text, &TreeBuilder).map_err(|e| {
        let shown: String = text.chars().take(50).collect();
        format!("'{shown}…' is not WKT this build reads: {e}")
    })
}

/// Refuses, before the recursive parser sees it, a text that does not open
/// as WKT does (a keyword and a bracket) or nests deeper than
/// [`MAX_DEPTH`]. The text itself is not quoted: it may be any file a
/// `.prj` or an option points at, and what is not WKT is not shown.
pub fn check_shape(text: &str) -> Result<(), String> {
    let keyword_len = text.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(text.len());
    let opens = text[keyword_len..].trim_start().starts_with(['[', '(']);
    if keyword_len == 0 || !opens {
        return Err("not WKT (it does not open with a keyword and a bracket, as PROJCS[ or GEOGCRS[ do)".to_string());
    }
    let (mut depth, mut quoted) = (0usize, false);
    for c in text.chars() {
        match c {
            '"' => quoted = !quoted,
            '[' | '(' if !quoted => {
                depth += 1;
                if depth > MAX_DEPTH {
                    return Err(format!("WKT nested more than {MAX_DEPTH} brackets deep (a CRS nests a few)"));
                }
            }
            ']' | ')' if !quoted => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(())
}

const HORIZONTAL: &[&str] = &["PROJCS", "PROJCRS", "PROJECTEDCRS", "GEOGCS", "GEOGCRS", "GEOGRAPHICCRS", "GEODCRS", "GEODETICCRS"];
const VERTICAL: &[&str] = &["VERT_CS", "VERTCRS", "VERTICALCRS"];
const DATUM: &[&str] = &["DATUM", "GEODETICDATUM", "TRF", "ENSEMBLE"];

impl Node {
    pub fn children(&self) -> impl Iterator<Item = &Node> {
        self.items.iter().filter_map(|i| match i {
            Item::Node(n) => Some(n),
            _ => None,
        })
    }

    fn child(&self, keys: &[&str]) -> Option<&Node> {
        self.children().find(|n| keys.contains(&n.key.as_str()))
    }

    /// The first quoted value: the name of a CRS, datum, parameter.
    pub fn name(&self) -> Option<&str> {
        self.items.iter().find_map(|i| match i {
            Item::Text(s) => Some(s.as_str()),
            _ => None,
        })
    }

    /// The EPSG code of this node's own `AUTHORITY` (WKT1) or `ID` (WKT2).
    pub fn epsg(&self) -> Option<u32> {
        self.children().filter(|n| n.key == "AUTHORITY" || n.key == "ID").find_map(|n| {
            let mut values = n.items.iter().filter_map(|i| match i {
                Item::Text(s) | Item::Number(s) | Item::Label(s) => Some(s.as_str()),
                Item::Node(_) => None,
            });
            let (authority, code) = (values.next()?, values.next()?);
            authority.eq_ignore_ascii_case("EPSG").then(|| code.trim().parse().ok()).flatten()
        })
    }

    /// The horizontal CRS: this node, the first part of a compound CRS, or
    /// the source of a WKT2 bound CRS.
    pub fn horizontal(&self) -> Option<&Node> {
        if HORIZONTAL.contains(&self.key.as_str()) {
            return Some(self);
        }
        match self.key.as_str() {
            "COMPD_CS" | "COMPOUNDCRS" => self.children().find_map(|n| n.horizontal()),
            "BOUNDCRS" => self.child(&["SOURCECRS"]).and_then(|s| s.children().find_map(|n| n.horizontal())),
            _ => None,
        }
    }

    /// The vertical part of a compound CRS.
    pub fn vertical(&self) -> Option<&Node> {
        match self.key.as_str() {
            "COMPD_CS" | "COMPOUNDCRS" => self.child(VERTICAL).or_else(|| self.children().find_map(|n| n.vertical())),
            "BOUNDCRS" => self.child(&["SOURCECRS"]).and_then(|s| s.children().find_map(|n| n.vertical())),
            _ => None,
        }
    }

    /// The geodetic datum (WKT1 `DATUM`, WKT2 `DATUM`/`TRF`/`ENSEMBLE`),
    /// wherever it sits below.
    pub fn datum(&self) -> Option<&Node> {
        self.child(DATUM).or_else(|| self.children().find_map(|n| n.datum()))
    }

    /// The first node below (depth first) with one of `keys`.
    pub fn find(&self, keys: &[&str]) -> Option<&Node> {
        self.child(keys).or_else(|| self.children().find_map(|n| n.find(keys)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deep_or_foreign_text_is_refused_without_being_quoted() {
        let deep = format!("GEOGCS[{}1{}", "A[".repeat(80_000), "]".repeat(80_000));
        assert!(parse(&deep).unwrap_err().contains("nested more than 64"));
        let e = parse("root:x:0:0:root:/root:/bin/bash").unwrap_err();
        assert!(!e.contains("root"), "{e}");
        // Brackets inside quoted names are not nesting.
        let quoted = format!("GEOGCS[\"{}\",DATUM[\"WGS_1984\"]]", "[".repeat(100));
        assert!(check_shape(&quoted).is_ok());
    }

    #[test]
    fn codes_names_and_parts() {
        let t = parse(r#"COMPD_CS["c",PROJCS["p",GEOGCS["g",DATUM["D_X",SPHEROID["s",1,2]],AUTHORITY["EPSG","4326"]],AUTHORITY["EPSG","32631"]],VERT_CS["v",VERT_DATUM["vd",2005],AUTHORITY["EPSG","5773"]]]"#).unwrap();
        assert_eq!(t.horizontal().unwrap().epsg(), Some(32631));
        assert_eq!(t.vertical().unwrap().epsg(), Some(5773));
        assert_eq!(t.horizontal().unwrap().datum().unwrap().name(), Some("D_X"));
        let w2 = parse(r#"PROJCRS["p",BASEGEOGCRS["g",DATUM["d",ELLIPSOID["e",1,2]]],CONVERSION["c",METHOD["m"]],ID["EPSG",2154]]"#).unwrap();
        assert_eq!(w2.horizontal().unwrap().epsg(), Some(2154));
        assert!(parse("PROJCS[\"unclosed\"").is_err());
    }
}
