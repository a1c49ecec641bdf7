//! The bounds on how many values, tables and arrays, and how many other tokens, a scene's
//! text holds, counted before the TOML parser sees it: the parser keeps 150 to 500 bytes for
//! each value with its place in the file, so a 12 MB array of numbers once took 900 MB, 3 MB
//! of inline tables 700 MB, and 1 MB of dotted keys 557 MB, before anything checked them;
//! and it lexes the whole text first, keeping 48 bytes for every token, so 60 MB of empty
//! lines (or of bare carriage returns, or of words) once took 2.9 GB.

/// The most values, tables and arrays a scene file may hold, counted as its commas, equals
/// signs, dots and opening brackets and braces outside strings and comments (each value but
/// an array's first comes after a comma or an equals sign; each table or array opens with a
/// bracket or brace, or a dot of a dotted key; a number's dot counts too): at most about
/// 500 MB of the parser's memory, and some 85,000 spheres written out one by one (about
/// twelve each). More spheres come from the scene's generators, which take a few lines.
pub const MAX_SCENE_VALUES: u64 = 1 << 20;

/// The most other tokens a scene file may hold: words (keys, numbers, `true`), strings,
/// comments, line ends, bare carriage returns, runs of blanks and closing brackets and
/// braces, each of which the parser keeps (48 bytes, so at most 200 MB). A sphere written
/// out takes about 28, a value in an array two: a file within `MAX_SCENE_VALUES` stays
/// within this.
pub const MAX_SCENE_TOKENS: u64 = 1 << 22;

/// Which bound a scene's text goes past.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bound {
    /// `MAX_SCENE_VALUES`.
    Values,
    /// `MAX_SCENE_TOKENS`.
    Tokens,
}

/// The bytes that end a word (the TOML lexer's atom): a quote does not, so `b"` is one word.
const WORD_ENDS: &[u8] = b".=,[]{} \t#\r\n";

/// The byte offset in `text` where it goes past `MAX_SCENE_VALUES` (the comma, equals sign,
/// dot, bracket or brace that does) or `MAX_SCENE_TOKENS` (the token that does), and which,
/// if it does. The text is cut into tokens as the TOML lexer (`toml_parser`) cuts it, which
/// it does to the whole text before the parser looks at any: a string on one line ends at
/// the line's end, a comment at a carriage return, a quote inside a word is the word's, and
/// each closing bracket or brace is a token. Read any other way, what the lexer keeps could
/// hide from the count (inside what the count took for a string, or in a run of `]`).
pub fn past_the_bound(text: &str) -> Option<(usize, Bound)> {
    let bytes = text.as_bytes();
    let (mut values, mut tokens) = (0u64, 0u64);
    let mut at = 0;
    while at < bytes.len() {
        let start = at;
        at = match bytes[at] {
            b',' | b'=' | b'[' | b'{' | b'.' => {
                values += 1;
                if values > MAX_SCENE_VALUES {
                    return Some((at, Bound::Values));
                }
                // A value's separator or opening: counted as a value, not again as a token.
                at += 1;
                continue;
            }
            b']' | b'}' | b'\n' => at + 1,
            b'\r' if bytes.get(at + 1) == Some(&b'\n') => at + 2,
            b'\r' => at + 1,
            b' ' | b'\t' => run_end(bytes, at, |b| b != b' ' && b != b'\t'),
            b'#' => run_end(bytes, at, |b| b == b'\r' || b == b'\n'),
            b'"' | b'\'' => string_end(bytes, at).unwrap_or(bytes.len()),
            _ => run_end(bytes, at, |b| WORD_ENDS.contains(&b)),
        };
        tokens += 1;
        if tokens > MAX_SCENE_TOKENS {
            return Some((start, Bound::Tokens));
        }
    }
    None
}

/// The offset just past the string that starts at `at` (at its quote), read as the lexer
/// reads it (`past_the_bound`), or None where no string starts there.
pub(super) fn string_end(bytes: &[u8], at: usize) -> Option<usize> {
    Some(match bytes.get(at)? {
        b'"' if bytes[at..].starts_with(b"\"\"\"") => multi_line_end(bytes, at + 3, b'"'),
        b'\'' if bytes[at..].starts_with(b"\'\'\'") => multi_line_end(bytes, at + 3, b'\''),
        b'"' => basic_string_end(bytes, at + 1),
        b'\'' => match bytes[at + 1..]
            .iter()
            .position(|&b| b == b'\'' || b == b'\n')
        {
            // Past the closing quote, or at the line end that cuts the string short.
            Some(n) => at + 1 + n + usize::from(bytes[at + 1 + n] == b'\''),
            None => bytes.len(),
        },
        _ => return None,
    })
}

/// The offset of the first byte after `at` for which `ends` holds (or the text's end).
fn run_end(bytes: &[u8], at: usize, ends: impl Fn(u8) -> bool) -> usize {
    bytes[at + 1..]
        .iter()
        .position(|&b| ends(b))
        .map_or(bytes.len(), |n| at + 1 + n)
}

/// The offset just past a basic string on one line whose text starts at `at`: past its
/// closing quote, or at the line end that cuts it short, or the text's end. A backslash
/// takes a following backslash or quote with it, as the lexer's does; not a line end.
fn basic_string_end(bytes: &[u8], mut at: usize) -> usize {
    while at < bytes.len() {
        match bytes[at] {
            b'"' => return at + 1,
            b'\n' => return at,
            b'\\' if matches!(bytes.get(at + 1), Some(b'\\' | b'"')) => at += 2,
            _ => at += 1,
        }
    }
    bytes.len()
}

/// The offset just past a multi-line string whose text starts at `at`, closed by three
/// `quote`s (or the text's end, where the lexer takes the rest as the string too). In a
/// basic one (`"`) a backslash takes a following backslash or quote with it. The closing
/// quotes may be followed by one or two more, which are its text (`'''a''''` is `a'`).
fn multi_line_end(bytes: &[u8], mut at: usize, quote: u8) -> usize {
    let close = [quote; 3];
    while at < bytes.len() {
        if quote == b'"' && bytes[at] == b'\\' {
            at += if matches!(bytes.get(at + 1), Some(b'\\' | b'"')) {
                2
            } else {
                1
            };
        } else if bytes[at..].starts_with(&close) {
            let mut end = at + 3;
            for _ in 0..2 {
                if bytes.get(end) == Some(&quote) {
                    end += 1;
                }
            }
            return end;
        } else {
            at += 1;
        }
    }
    bytes.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separators_in_strings_and_comments_are_not_values() {
        let n = MAX_SCENE_VALUES as usize;
        let quoted = format!("a = \"{}\"\n", ",".repeat(n + 10));
        assert_eq!(past_the_bound(&quoted), None);
        let literal = format!("a = '''{}'''\n", "=".repeat(n + 10));
        assert_eq!(past_the_bound(&literal), None);
        let escaped = format!("a = \"\\\"{}\"\n", ",".repeat(n + 10));
        assert_eq!(past_the_bound(&escaped), None);
        let comment = format!("# {}\na = 1\n", ",".repeat(n + 10));
        assert_eq!(past_the_bound(&comment), None);
    }

    #[test]
    fn the_separator_past_the_bound_is_found() {
        let n = MAX_SCENE_VALUES as usize;
        // The equals sign, the bracket and n - 2 commas are within.
        let within = format!("a = [{}]\n", vec!["1"; n - 1].join(","));
        assert_eq!(past_the_bound(&within), None);
        // The (n - 1)-th comma is not.
        let over = format!("a = [{}]\n", vec!["1"; n].join(","));
        assert_eq!(
            past_the_bound(&over),
            Some((4 + 2 * (n - 1), Bound::Values))
        );
        // Tables count by their headers' brackets, inline ones by their braces.
        let tables = "[[s]]\n".repeat(n / 2 + 1);
        assert_eq!(past_the_bound(&tables), Some((6 * (n / 2), Bound::Values)));
        let inline = format!("a = [{}]", vec!["{}"; n].join(","));
        assert!(past_the_bound(&inline).is_some());
    }

    #[test]
    fn quotes_after_a_multi_line_string_s_close_are_its_own() {
        let n = MAX_SCENE_VALUES as usize;
        for (open, close) in [("'''", "''''"), ("\"\"\"", "\"\"\"\""), ("'''", "'''''")] {
            // Read as a string from the stray quote, the numbers would hide in it.
            let q = &close[..1];
            let text = format!(
                "x = {open}a{close}\nv = [{}] # {q}\n",
                vec!["1"; n].join(",")
            );
            assert!(past_the_bound(&text).is_some(), "{open}…{close}");
        }
    }

    #[test]
    fn dotted_keys_count_as_the_tables_they_make() {
        let n = MAX_SCENE_VALUES as usize;
        let key = vec!["x"; 60].join(".");
        let lines = n / 60 + 1;
        let text: String = (0..lines).map(|i| format!("k{i}.{key} = 1\n")).collect();
        assert!(past_the_bound(&text).is_some());
    }

    #[test]
    fn an_open_string_ends_the_count() {
        let open = format!("a = \"{}", ",".repeat(10));
        assert_eq!(past_the_bound(&open), None);
    }

    #[test]
    fn what_the_lexer_keeps_cannot_hide_where_the_count_does_not_look() {
        let n = MAX_SCENE_VALUES as usize;
        let values = format!("v = [{}]\n", vec!["1"; n].join(","));
        // The lexer ends a string on one line at its line end, a comment at a carriage
        // return, and takes a quote inside a word as the word's: the numbers that follow are
        // its tokens, as they are the count's.
        for (name, opening, closing) in [
            ("a basic string left open", "a = \"\n", "# \""),
            ("a literal string left open", "a = '\n", "# '"),
            ("an escaped line end", "a = \"\\\n", "# \""),
            ("a comment cut by a carriage return", "# \r", ""),
            ("a quote inside a word", "a = b\"\n", "# \""),
            ("a quote inside a literal word", "a = b'\n", "# '"),
        ] {
            let text = format!("{opening}{values}{closing}\n");
            assert_eq!(
                past_the_bound(&text).map(|(_, bound)| bound),
                Some(Bound::Values),
                "{name}"
            );
        }
        // Each closing bracket or brace is a token of the lexer's, however many in a row.
        let m = MAX_SCENE_TOKENS as usize;
        for close in ["]", "}", "]}"] {
            let text = format!("a = {}", close.repeat(m / close.len() + 1));
            assert_eq!(
                past_the_bound(&text),
                Some((4 + m - 3, Bound::Tokens)),
                "{close}"
            );
        }
        // Strings that do end on their line still hide what they hold.
        let escaped = format!("a = \"\\\\{}\\\"\"\n", ",".repeat(n + 10));
        assert_eq!(past_the_bound(&escaped), None);
        let multi = format!("a = \"\"\"\n\\\"\"\"{}\n\"\"\"\n", ",".repeat(n + 10));
        assert_eq!(past_the_bound(&multi), None);
    }

    #[test]
    fn line_ends_words_strings_and_blanks_count_as_the_tokens_they_are() {
        let n = MAX_SCENE_TOKENS as usize;
        // Within: n line ends, CRLF one each.
        assert_eq!(past_the_bound(&"\r\n".repeat(n)), None);
        assert_eq!(
            past_the_bound(&"\n".repeat(n + 1)),
            Some((n, Bound::Tokens))
        );
        // A carriage return alone, a word, a string, a comment and a run of blanks are one
        // token each; a run is one however long.
        assert_eq!(
            past_the_bound(&"\r".repeat(n + 1)),
            Some((n, Bound::Tokens))
        );
        assert_eq!(
            past_the_bound(&"ab ".repeat(n / 2 + 1)),
            Some((3 * (n / 2), Bound::Tokens))
        );
        assert_eq!(
            past_the_bound(&"\"a\"".repeat(n + 1)),
            Some((3 * n, Bound::Tokens))
        );
        assert_eq!(
            past_the_bound(&"#,,\n".repeat(n / 2 + 1)),
            Some((4 * (n / 2), Bound::Tokens))
        );
        assert_eq!(past_the_bound(&" \t ".repeat(n)), None);
        // Written out one by one, the most spheres the values allow stay within.
        let sphere = "[[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = 0.5\nmaterial = \"m\"\n";
        let spheres = sphere.repeat(85_000);
        assert_eq!(past_the_bound(&spheres), None);
    }
}
