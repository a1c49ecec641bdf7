//! What the TOML parser says of a scene file, in the scene's own terms: the keys to a value
//! as the file names them, the table a missing key is missing from, plain type names, and
//! where a key or value nests deeper than the parser goes, and in which field.

use super::values::string_end;

/// The keys to a value as a scene file names them (`spheres[2].center`), without the
/// wrappers that keep each value's place in the file.
pub(super) fn key_path(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    let mut named = String::new();
    for segment in path.iter() {
        match segment {
            Segment::Seq { index } => named.push_str(&format!("[{index}]")),
            Segment::Map { key } | Segment::Enum { variant: key } => {
                if key.starts_with("$__serde_spanned") {
                    continue;
                }
                if !named.is_empty() {
                    named.push('.');
                }
                named.push_str(key);
            }
            Segment::Unknown => {}
        }
    }
    named
}

/// The tables a scene file holds at its top level (`desc::SceneDesc`'s fields).
const TOP_LEVEL: [&str; 14] = [
    "image",
    "render",
    "camera",
    "background",
    "textures",
    "materials",
    "spheres",
    "quads",
    "rects",
    "boxes",
    "media",
    "random_spheres",
    "random_boxes",
    "random_sphere_clouds",
];

/// A missing key's message with the table it is missing from: for a whole table, the
/// file's top level; else the table whose header starts the line at `start` (where the
/// parser points), `[[spheres]]` counted (`#2`), or the key of an inline table on it.
pub(super) fn name_the_table(text: &str, start: usize, message: &str) -> String {
    let Some(key) = message
        .strip_prefix("missing field `")
        .and_then(|m| m.strip_suffix('`'))
    else {
        return message.to_owned();
    };
    if TOP_LEVEL.contains(&key) {
        return format!(
            "missing table [{key}] at the top level of the file; docs/scene-format.md lists \
             every key"
        );
    }
    let line_start = text
        .get(..start)
        .map_or(0, |t| t.rfind('\n').map_or(0, |i| i + 1));
    let line = text
        .get(line_start..)
        .unwrap_or("")
        .lines()
        .next()
        .unwrap_or("");
    let header = line.split('#').next().unwrap_or("").trim();
    let inline = header
        .split_once('=')
        .filter(|(_, value)| value.trim_start().starts_with(['{', '[']))
        .map(|(name, _)| name.trim());
    if let Some(name) = inline {
        return format!("`{name}`: missing key `{key}`; docs/scene-format.md lists every key");
    }
    let Some(name) = header
        .strip_prefix('[')
        .and_then(|h| h.strip_suffix(']'))
        .map(|h| h.trim_matches(['[', ']']).trim())
    else {
        return format!("missing key `{key}`; docs/scene-format.md lists every key");
    };
    let table = if header.starts_with("[[") {
        // Which of the array's tables: count the headers of the same name up to here.
        let nth = text[..line_start]
            .lines()
            .filter(|l| l.split('#').next().unwrap_or("").trim() == header)
            .count()
            + 1;
        format!("{header} #{nth}")
    } else {
        header.to_owned()
    };
    let hint = match (name, key) {
        ("image", "max_depth") => " (the most ray segments per path: the book uses 50)",
        ("image", "samples_per_pixel") => " (samples per pixel: the book uses 100)",
        ("image", "width" | "height") => " (the image's size in pixels)",
        _ => "",
    };
    format!("{table}: missing key `{key}`{hint}; docs/scene-format.md lists every key")
}

/// Serde names Rust types in its messages; a scene author knows TOML's. An integer past
/// what its field's type holds is said as such, with the range (serde says "invalid type:
/// integer `1e23…` as i128, expected i64", which reads as a complaint about its type).
pub(super) fn plain_types(message: &str) -> String {
    if let Some(said) = out_of_range(message) {
        return said;
    }
    message
        .replace("expected i64", "expected an integer")
        .replace("expected u64", "expected a non-negative integer")
        .replace("expected f64", "expected a number")
        .replace("a spanned value", "a value")
}

/// The message for an integer too large (or, for a non-negative field, negative) for its
/// field's type, from serde's ("invalid type: integer `N` as i128, expected i64", "invalid
/// value: integer `N`, expected u64"), or None for any other message. TOML's integers are
/// 64-bit: a number field takes a larger one written as a float (`1e23`).
fn out_of_range(message: &str) -> Option<String> {
    let rest = (message.strip_prefix("invalid type: integer `"))
        .or_else(|| message.strip_prefix("invalid value: integer `"))?;
    let (number, after) = rest.split_once('`')?;
    let expected = (after.strip_prefix(" as i128, expected "))
        .or_else(|| after.strip_prefix(", expected "))?;
    let range = match expected {
        "i64" => format!("an integer from {} to {}", i64::MIN, i64::MAX),
        "u64" => format!("an integer from 0 to {}", u64::MAX),
        "f64" => {
            return Some(format!(
                "integer `{number}` is out of range: TOML's integers are from {} to {}; \
                 write a number this large with an exponent (`1e23`)",
                i64::MIN,
                i64::MAX
            ));
        }
        _ => return None,
    };
    Some(format!(
        "integer `{number}` is out of range: this field is {range}"
    ))
}

/// How deep the TOML parser (`toml`'s `LIMIT`) lets keys and values nest: a dotted key of
/// more parts, or arrays and inline tables nested deeper, are refused by it, a key with no
/// place in the file ("recursion limit", which would read as line 1) and a value with no
/// field ("cannot recurse further").
pub(super) const PARSER_NESTING: usize = 80;

/// What the parser's message `message` at `start` says, where it is its refusal of keys or
/// values nested past `PARSER_NESTING`: where (a key's start; the parser gives none), the
/// field that holds it where there is one, and the message in the scene's terms.
pub(super) fn too_deep(
    text: &str,
    start: usize,
    message: &str,
) -> Option<(usize, Option<String>, String)> {
    if message == "recursion limit" {
        let at = long_dotted_key(text).unwrap_or(start);
        return Some((
            at,
            None,
            format!(
                "a dotted key of more than {PARSER_NESTING} parts, more than the TOML parser \
                 takes; a scene's keys need a few"
            ),
        ));
    }
    if !message.starts_with("cannot recurse further") {
        return None;
    }
    let field = field_holding(text, start);
    Some((
        start,
        (!field.is_empty()).then_some(field),
        format!(
            "arrays and inline tables nested more than {PARSER_NESTING} deep, more than the \
             TOML parser takes; a scene's values nest a few deep"
        ),
    ))
}

/// The start of the first dotted key in `text` of more than `PARSER_NESTING` parts:
/// a run of words and quoted keys joined by dots (and blanks), outside comments. A number
/// has one dot at most, so only a key (or what is no TOML at all) makes such a run.
fn long_dotted_key(text: &str) -> Option<usize> {
    let bytes = text.as_bytes();
    let (mut at, mut run_start, mut dots) = (0, None, 0);
    while at < bytes.len() {
        match bytes[at] {
            b'#' => {
                at = bytes[at..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(bytes.len(), |n| at + n);
                (run_start, dots) = (None, 0);
                continue;
            }
            b'"' | b'\'' => {
                run_start.get_or_insert(at);
                at = string_end(bytes, at).unwrap_or(bytes.len());
                continue;
            }
            b'.' => {
                dots += 1;
                if dots >= PARSER_NESTING {
                    return run_start;
                }
            }
            b' ' | b'\t' => {}
            b if b.is_ascii_alphanumeric() || b == b'_' || b == b'-' => {
                run_start.get_or_insert(at);
            }
            _ => (run_start, dots) = (None, 0),
        }
        at += 1;
    }
    None
}

/// The field whose value holds the offset `at`: the table whose header is the last before
/// it at the top level, and the key whose value it is in (`random_spheres.keep_clear`);
/// empty where there is neither. Strings and comments are passed over.
fn field_holding(text: &str, at: usize) -> String {
    let bytes = text.as_bytes();
    let end = at.min(bytes.len());
    let (mut i, mut depth, mut in_value) = (0, 0usize, false);
    let (mut table, mut key, mut key_start) = (String::new(), String::new(), 0);
    while i < end {
        match bytes[i] {
            b'#' => {
                i = bytes[i..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(bytes.len(), |n| i + n);
                continue;
            }
            b'"' | b'\'' => {
                i = string_end(bytes, i).unwrap_or(bytes.len());
                continue;
            }
            b'\n' if depth == 0 => (in_value, key_start) = (false, i + 1),
            b'=' if depth == 0 && !in_value => {
                key = text.get(key_start..i).unwrap_or("").trim().to_owned();
                in_value = true;
            }
            b'[' | b'{' if in_value => depth += 1,
            b']' | b'}' if in_value => depth = depth.saturating_sub(1),
            b'[' if depth == 0 => {
                // A table's header: its name, up to its line's end.
                let line_end = bytes[i..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(bytes.len(), |n| i + n);
                let header = text.get(i..line_end).unwrap_or("");
                let header = header.split('#').next().unwrap_or("").trim();
                table = header.trim_matches(['[', ']']).trim().to_owned();
                key.clear();
                i = line_end;
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    match (table.is_empty(), key.is_empty()) {
        (_, true) => table,
        (true, false) => key,
        (false, false) => format!("{table}.{key}"),
    }
}
