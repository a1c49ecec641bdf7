//! The bound on how many values, tables and arrays a scene's text holds, counted before
//! the TOML parser sees it: the parser keeps 150 to 500 bytes for each with its place in
//! the file, so a 12 MB array of numbers once took 900 MB, 3 MB of inline tables 700 MB,
//! and 1 MB of dotted keys 557 MB, before anything checked them.

/// The most values, tables and arrays a scene file may hold, counted as its commas, equals
/// signs, dots and opening brackets and braces outside strings and comments (each value but
/// an array's first comes after a comma or an equals sign; each table or array opens with a
/// bracket or brace, or a dot of a dotted key; a number's dot counts too): at most about
/// 500 MB of the parser's memory, and some 85,000 spheres written out one by one (about
/// twelve each). More spheres come from the scene's generators, which take a few lines.
pub const MAX_SCENE_VALUES: u64 = 1 << 20;

/// The byte offset in `text` of the comma, equals sign, dot, bracket or brace that takes it past
/// `MAX_SCENE_VALUES`, if one does. A string left open ends the count: the parser then
/// says what is wrong with it.
pub fn past_the_bound(text: &str) -> Option<usize> {
    let bytes = text.as_bytes();
    let mut count = 0u64;
    let mut at = 0;
    while at < bytes.len() {
        match bytes[at] {
            b'#' => at = end_of_line(bytes, at),
            b'"' if bytes[at..].starts_with(b"\"\"\"") => {
                at = end_of_string(bytes, at + 3, b"\"\"\"", true)?
            }
            b'"' => at = end_of_string(bytes, at + 1, b"\"", true)?,
            b'\'' if bytes[at..].starts_with(b"'''") => {
                at = end_of_string(bytes, at + 3, b"'''", false)?
            }
            b'\'' => at = end_of_string(bytes, at + 1, b"'", false)?,
            b',' | b'=' | b'[' | b'{' | b'.' => {
                count += 1;
                if count > MAX_SCENE_VALUES {
                    return Some(at);
                }
                at += 1;
            }
            _ => at += 1,
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
        assert_eq!(past_the_bound(&over), Some(4 + 2 * (n - 1)));
        // Tables count by their headers' brackets, inline ones by their braces.
        let tables = "[[s]]\n".repeat(n / 2 + 1);
        assert_eq!(past_the_bound(&tables), Some(6 * (n / 2)));
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
}
