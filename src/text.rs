//! Text a stranger wrote (a CPU model in an imported result, a recipe in an image), made safe
//! to print to a terminal, where an escape sequence could rewrite the screen, or to put in a
//! web page, where markup or a bidirectional override could change what it shows; and a
//! count with its noun (`1 run`, `2 runs`), as every message says one.

/// Whether `c` must not reach a terminal or a page as it is: a control character (Unicode's
/// Cc), a line or paragraph separator (Zl, Zp), or a format character (Cf), which reorders,
/// joins or hides what is around it: bidirectional marks and overrides, zero-width
/// characters, the byte order mark, invisible operators, tags.
pub fn is_unsafe(c: char) -> bool {
    c.is_control()
        || matches!(
            c,
            '\u{ad}'
                | '\u{600}'..='\u{605}'
                | '\u{61c}'
                | '\u{6dd}'
                | '\u{70f}'
                | '\u{890}'..='\u{891}'
                | '\u{8e2}'
                | '\u{180e}'
                | '\u{200b}'..='\u{200f}'
                | '\u{2028}'..='\u{202e}'
                | '\u{2060}'..='\u{2064}'
                | '\u{2066}'..='\u{206f}'
                | '\u{feff}'
                | '\u{fff9}'..='\u{fffb}'
                | '\u{110bd}'
                | '\u{110cd}'
                | '\u{13430}'..='\u{1343f}'
                | '\u{1bca0}'..='\u{1bca3}'
                | '\u{1d173}'..='\u{1d17a}'
                | '\u{e0001}'
                | '\u{e0020}'..='\u{e007f}'
        )
}

/// JSON text with every character beyond ASCII written as a `\uXXXX` escape (UTF-16, as
/// JSON has it): the same JSON value, safe for a terminal, and carried unchanged by formats
/// whose text is Latin-1 or bytes (EXR attributes). Characters escaped by the JSON already
/// (controls) stay so.
pub fn ascii_json(json: &str) -> String {
    let mut out = String::with_capacity(json.len());
    for c in json.chars() {
        if c.is_ascii() {
            out.push(c);
        } else {
            let mut units = [0u16; 2];
            for unit in c.encode_utf16(&mut units) {
                out.push_str(&format!("\\u{unit:04x}"));
            }
        }
    }
    out
}

/// `text` as one line safe to print: unsafe characters (newlines too) shown as `\u{…}`
/// escapes, and cut to `width` characters.
pub fn terminal_safe(text: &str, width: usize) -> String {
    let mut out = String::new();
    for (i, c) in text.chars().enumerate() {
        if i == width {
            out.push('…');
            break;
        }
        if is_unsafe(c) {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
    }
    out
}

/// A file's path as one line safe to print (`terminal_safe`, whole): a name a stranger chose
/// (`a\nidentical: b.png`) must not start a line of its own in a verdict, such as a forged
/// `identical:` under a real `differs:`.
pub fn path_safe(path: &std::path::Path) -> String {
    terminal_safe(&path.display().to_string(), usize::MAX)
}

/// The most characters of an error message printed: a message quotes what a stranger wrote
/// (a scene's key, a material's name) whole, and a scene file's key of 60 MiB once made a
/// message of 120 MB, one line on the terminal.
pub const MAX_MESSAGE_CHARS: usize = 4096;

/// An error message as one line safe to print (`terminal_safe`), of at most
/// `MAX_MESSAGE_CHARS` of its characters: a longer one keeps its start and its end, which
/// say where and why, and says how many characters between them are left out.
pub fn message_safe(text: &str) -> String {
    let count = text.chars().count();
    if count <= MAX_MESSAGE_CHARS {
        return terminal_safe(text, usize::MAX);
    }
    let half = MAX_MESSAGE_CHARS / 2;
    let tail = (text.char_indices().nth(count - half)).map_or(text.len(), |(at, _)| at);
    let head: String = text.chars().take(half).collect();
    format!(
        "{} … ({} characters left out) … {}",
        terminal_safe(&head, usize::MAX),
        count - 2 * half,
        terminal_safe(&text[tail..], usize::MAX)
    )
}

/// `text` of many lines safe to print: newlines and tabs kept, other unsafe characters
/// escaped.
pub fn terminal_safe_lines(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if is_unsafe(c) && c != '\n' && c != '\t' {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
    }
    out
}

/// Whether `c` is one of Unicode's noncharacters (U+FDD0 to U+FDEF, and the last two of
/// each plane), which no text exchanged holds: XML allows neither U+FFFE nor U+FFFF, and
/// one of them in an SVG file made the whole file an error in a browser, its chart unshown.
fn is_noncharacter(c: char) -> bool {
    matches!(c, '\u{fdd0}'..='\u{fdef}') || (c as u32) & 0xfffe == 0xfffe
}

/// `text` for HTML text and attribute values, and for SVG and XML files: markup characters
/// as entities, and what must not reach a terminal (controls, bidirectional overrides) or
/// an XML file (noncharacters) as `\u{…}`, as a reader of the page could otherwise see
/// another text than the one there, or none.
pub fn html_safe(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c if is_unsafe(c) || is_noncharacter(c) => out.extend(c.escape_unicode()),
            c => out.push(c),
        }
    }
    out
}

/// `n` and the noun, singular for one: `1 thread`, `2 threads`.
pub fn count(n: impl Into<u64>, noun: &str) -> String {
    let n = n.into();
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// `x` with `digits` significant digits, without an exponent for everyday magnitudes:
/// `0.0001234` rather than `0.000123` or `0.000000` for a small but real difference.
pub fn significant(x: f64, digits: usize) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let magnitude = x.abs().log10().floor() as i32;
    if !(-9..=9).contains(&magnitude) {
        return format!("{:.*e}", digits.saturating_sub(1), x);
    }
    let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
    format!("{x:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_message_keeps_its_start_and_end() {
        assert_eq!(message_safe("short\u{1b}"), "short\\u{1b}");
        let key = "k".repeat(3 * MAX_MESSAGE_CHARS);
        let long = format!("s.toml:2:1: field `{key}`: unknown field, expected `width`\u{1b}");
        let said = message_safe(&long);
        assert!(said.starts_with("s.toml:2:1: field `kkk"), "{said}");
        assert!(
            said.ends_with("kkk`: unknown field, expected `width`\\u{1b}"),
            "{said}"
        );
        let left_out = long.chars().count() - MAX_MESSAGE_CHARS;
        assert!(said.contains(&format!(" … ({left_out} characters left out) … ")));
        assert!(
            said.chars().count() < MAX_MESSAGE_CHARS + 60,
            "{}",
            said.len()
        );
    }

    #[test]
    fn controls_and_bidi_are_escaped() {
        assert_eq!(terminal_safe("a\nb\u{202e}c", 20), "a\\u{a}b\\u{202e}c");
        assert_eq!(terminal_safe("abcdef", 3), "abc…");
        assert_eq!(
            terminal_safe_lines("a\n\u{1b}[2J\tb\u{2066}"),
            "a\n\\u{1b}[2J\tb\\u{2066}"
        );
        for invisible in ['\u{61c}', '\u{2028}', '\u{2029}', '\u{feff}', '\u{e0041}'] {
            assert_eq!(
                terminal_safe(&format!("a{invisible}b"), 20),
                format!("a{}b", invisible.escape_unicode())
            );
        }
        assert_eq!(
            ascii_json("\"\u{202e}é𝄞\""),
            "\"\\u202e\\u00e9\\ud834\\udd1e\""
        );
        assert_eq!(
            html_safe("<b a=\"x\">&'\u{202e}</b>"),
            "&lt;b a=&quot;x&quot;&gt;&amp;&#39;\\u{202e}&lt;/b&gt;"
        );
        // What XML does not allow, which made a chart's whole SVG file an error.
        assert_eq!(
            html_safe("a\u{fffe}\u{ffff}\u{fdd0}\u{10ffff}\u{fffd}b"),
            "a\\u{fffe}\\u{ffff}\\u{fdd0}\\u{10ffff}\u{fffd}b"
        );
    }
}
