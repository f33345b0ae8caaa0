//! The INI layer of CiA 306 §4: `[section]` headers, `key=value` lines and `;` comments, with
//! the line of each so that every later error can name it. Section names and keys are not
//! case-sensitive (CiA 306 §4.1); each may appear once.

use super::error::{EdsError, Location};

/// One `key=value` line.
#[derive(Debug, Clone)]
pub struct Key {
    pub name: String,
    pub value: String,
    pub line: usize,
}

/// One section with its keys in file order.
#[derive(Debug, Clone)]
pub struct Section {
    pub name: String,
    pub line: usize,
    pub keys: Vec<Key>,
}

/// A parsed file: its sections in file order.
#[derive(Debug, Clone)]
pub struct Ini {
    pub file: String,
    pub sections: Vec<Section>,
}

impl Ini {
    /// Splits `text` into sections and keys. A comment starts with `;` at the start of a line
    /// or after white space (python-canopen's reading: `inline_comment_prefixes=(';',)`).
    pub fn parse(text: &str, file: &str) -> Result<Ini, EdsError> {
        let mut sections: Vec<Section> = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = i + 1;
            let content = strip_comment(raw).trim();
            if content.is_empty() {
                continue;
            }
            if let Some(rest) = content.strip_prefix('[') {
                let name = rest
                    .strip_suffix(']')
                    .map(str::trim)
                    .filter(|n| !n.is_empty())
                    .ok_or_else(|| EdsError::Syntax {
                        file: file.to_owned(),
                        line,
                        what: format!("{content:?} is not a section header [NAME]"),
                    })?;
                if let Some(first) = sections.iter().find(|s| s.name.eq_ignore_ascii_case(name)) {
                    return Err(EdsError::Duplicate {
                        at: Location {
                            file: file.to_owned(),
                            line,
                            section: name.to_owned(),
                            key: String::new(),
                        },
                        first_line: first.line,
                    });
                }
                sections.push(Section {
                    name: name.to_owned(),
                    line,
                    keys: Vec::new(),
                });
                continue;
            }
            let Some((key, value)) = content.split_once('=') else {
                return Err(EdsError::Syntax {
                    file: file.to_owned(),
                    line,
                    what: format!("{content:?} is neither [SECTION] nor KEY=VALUE"),
                });
            };
            let key = key.trim();
            let Some(section) = sections.last_mut() else {
                return Err(EdsError::Syntax {
                    file: file.to_owned(),
                    line,
                    what: format!("{key}= before the first [SECTION]"),
                });
            };
            if key.is_empty() {
                return Err(EdsError::Syntax {
                    file: file.to_owned(),
                    line,
                    what: "a line =VALUE without a key".to_owned(),
                });
            }
            if let Some(first) = section
                .keys
                .iter()
                .find(|k| k.name.eq_ignore_ascii_case(key))
            {
                return Err(EdsError::Duplicate {
                    at: Location {
                        file: file.to_owned(),
                        line,
                        section: section.name.clone(),
                        key: key.to_owned(),
                    },
                    first_line: first.line,
                });
            }
            section.keys.push(Key {
                name: key.to_owned(),
                value: value.trim().to_owned(),
                line,
            });
        }
        Ok(Ini {
            file: file.to_owned(),
            sections,
        })
    }

    pub fn section(&self, name: &str) -> Option<&Section> {
        self.sections
            .iter()
            .find(|s| s.name.eq_ignore_ascii_case(name))
    }

    /// The location of `key` in `section` (the key's line, or the section's if the key is
    /// absent).
    pub fn at(&self, section: &Section, key: &str) -> Location {
        Location {
            file: self.file.clone(),
            line: section.key(key).map_or(section.line, |k| k.line),
            section: section.name.clone(),
            key: key.to_owned(),
        }
    }
}

impl Section {
    pub fn key(&self, name: &str) -> Option<&Key> {
        self.keys.iter().find(|k| k.name.eq_ignore_ascii_case(name))
    }
    pub fn value(&self, name: &str) -> Option<&str> {
        self.key(name).map(|k| k.value.as_str())
    }
}

/// `line` without a `;` comment (at the start, or after white space).
fn strip_comment(line: &str) -> &str {
    let mut prev_space = true;
    for (i, c) in line.char_indices() {
        if c == ';' && prev_space {
            return line.get(..i).unwrap_or("");
        }
        prev_space = c.is_whitespace();
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sections_keys_comments_and_lines() {
        let ini = Ini::parse(
            "; a comment\n[FileInfo]\nFileName = x.eds ; trailing\n\n[1000]\nParameterName=Device type;1\n",
            "x.eds",
        )
        .unwrap();
        assert_eq!(ini.sections.len(), 2);
        let fi = ini.section("fileinfo").unwrap();
        assert_eq!(fi.line, 2);
        assert_eq!(fi.value("FILENAME"), Some("x.eds"));
        assert_eq!(fi.key("FileName").unwrap().line, 3);
        // A `;` inside a word is text, not a comment.
        assert_eq!(
            ini.section("1000").unwrap().value("ParameterName"),
            Some("Device type;1")
        );
    }

    #[test]
    fn mistakes_name_their_line() {
        let e = Ini::parse("[A]\nx=1\n[a]\n", "f.eds").unwrap_err();
        assert_eq!(e.to_string(), "f.eds:3: [a]: given twice (first at line 1)");
        let e = Ini::parse("[A]\nx=1\nX=2\n", "f.eds").unwrap_err();
        assert_eq!(
            e.to_string(),
            "f.eds:3: [A] X: given twice (first at line 2)"
        );
        let e = Ini::parse("[A]\njunk\n", "f.eds").unwrap_err();
        assert!(e.to_string().starts_with("f.eds:2: "), "{e}");
        let e = Ini::parse("x=1\n", "f.eds").unwrap_err();
        assert!(e.to_string().starts_with("f.eds:1: "), "{e}");
        // CR LF line ends, as most EDS tools write them.
        let ini = Ini::parse("[A]\r\nx = 1\r\n", "f.eds").unwrap();
        assert_eq!(ini.section("a").unwrap().value("x"), Some("1"));
        let e = Ini::parse("[A\n", "f.eds").unwrap_err();
        assert!(e.to_string().contains("section header"), "{e}");
    }
}
