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
/// comments, line ends, bare carriage returns and runs of blanks, each of which the parser
/// keeps (48 bytes, so at most 200 MB). A sphere written out takes about 25, a value in an
/// array two: a file within `MAX_SCENE_VALUES` stays within this.
pub const MAX_SCENE_TOKENS: u64 = 1 << 22;

/// Which bound a scene's text goes past.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bound {
    /// `MAX_SCENE_VALUES`.
    Values,
    /// `MAX_SCENE_TOKENS`.
    Tokens,
}

/// What a byte outside strings and comments starts, for counting runs of them as one token.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Run {
    None,
    Blanks,
    Word,
}

/// The byte offset in `text` where it goes past `MAX_SCENE_VALUES` (the comma, equals sign,
/// dot, bracket or brace that does) or `MAX_SCENE_TOKENS` (the token that does), and which,
/// if it does. A string left open ends the count: the parser then says what is wrong with
/// it.
pub fn past_the_bound(text: &str) -> Option<(usize, Bound)> {
    let bytes = text.as_bytes();
    let (mut values, mut tokens) = (0u64, 0u64);
    let mut run = Run::None;
    let mut at = 0;
    while at < bytes.len() {
        let start = at;
        // Each token but a value's separator, and what comes after it.
        let (token, next) = match bytes[at] {
            b'#' => {
                at = end_of_line(bytes, at);
                (true, Run::None)
            }
            b'"' if bytes[at..].starts_with(b"\"\"\"") => {
                at = end_of_string(bytes, at + 3, b"\"\"\"", true)?;
                (true, Run::None)
            }
            b'"' => {
                at = end_of_string(bytes, at + 1, b"\"", true)?;
                (true, Run::None)
            }
            b'\'' if bytes[at..].starts_with(b"'''") => {
                at = end_of_string(bytes, at + 3, b"'''", false)?;
                (true, Run::None)
            }
            b'\'' => {
                at = end_of_string(bytes, at + 1, b"\'", false)?;
                (true, Run::None)
            }
            b',' | b'=' | b'[' | b'{' | b'.' => {
                values += 1;
                if values > MAX_SCENE_VALUES {
                    return Some((at, Bound::Values));
                }
                at += 1;
                (false, Run::None)
            }
            // A line end, CRLF as one; a carriage return alone is a token of its own.
            b'\r' if bytes.get(at + 1) == Some(&b'\n') => {
                at += 2;
                (true, Run::None)
            }
            b'\n' | b'\r' => {
                at += 1;
                (true, Run::None)
            }
            b' ' | b'\t' => {
                at += 1;
                (run != Run::Blanks, Run::Blanks)
            }
            _ => {
                at += 1;
                (run != Run::Word, Run::Word)
            }
        };
        run = next;
        if token {
            tokens += 1;
            if tokens > MAX_SCENE_TOKENS {
                return Some((start, Bound::Tokens));
            }
        }
    }
    None
}

/// The offset of the newline ending the comment at `at` (or the end of the text).
fn end_of_line(bytes: &[u8], at: usize) -> usize {
    bytes[at..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(bytes.len(), |n| at + n)
}

/// The offset just past the `close` that ends a string whose text starts at `at`; `escapes`
/// for a basic string, where a backslash takes the next byte with it. None when the string
/// never ends. A multi-line string's closing quotes may be followed by one or two more,
/// which are its text (`'''a''''` is `a'`).
fn end_of_string(bytes: &[u8], mut at: usize, close: &[u8], escapes: bool) -> Option<usize> {
    while at < bytes.len() {
        if escapes && bytes[at] == b'\\' {
            at += 2;
        } else if bytes[at..].starts_with(close) {
            let mut end = at + close.len();
            if close.len() == 3 {
                let quote = close[0];
                for _ in 0..2 {
                    if bytes.get(end) == Some(&quote) {
                        end += 1;
                    }
                }
            }
            return Some(end);
        } else {
            at += 1;
        }
    }
    None
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
