//! Text a stranger wrote (a CPU model in an imported result, a recipe in an image), made safe
//! to print to a terminal, where an escape sequence could rewrite the screen, or to put in a
//! web page, where markup or a bidirectional override could change what it shows.

/// Whether `c` must not reach a terminal as it is: a control character, or one that
/// reorders or hides what follows (bidirectional overrides, zero-width marks).
fn is_unsafe(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{200b}'..='\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
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

/// `text` for HTML text and attribute values: markup characters as entities, and what
/// must not reach a terminal (controls, bidirectional overrides) as `\u{…}`, as a reader of
/// the page could otherwise see another text than the one there.
pub fn html_safe(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c if is_unsafe(c) => out.extend(c.escape_unicode()),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn controls_and_bidi_are_escaped() {
        assert_eq!(terminal_safe("a\nb\u{202e}c", 20), "a\\u{a}b\\u{202e}c");
        assert_eq!(terminal_safe("abcdef", 3), "abc…");
        assert_eq!(
            terminal_safe_lines("a\n\u{1b}[2J\tb\u{2066}"),
            "a\n\\u{1b}[2J\tb\\u{2066}"
        );
        assert_eq!(
            html_safe("<b a=\"x\">&'\u{202e}</b>"),
            "&lt;b a=&quot;x&quot;&gt;&amp;&#39;\\u{202e}&lt;/b&gt;"
        );
    }
}
