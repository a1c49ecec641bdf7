//! Flags that several commands share (`--simd`, `--db`, `--threads`), and the parsers of
//! numbers typed on the command line: a negative number is read as a number, not taken for
//! a flag, and refused with the range the flag accepts.

use anyhow::Result;
use clap::Args;
use tessera::simd;

/// `--simd`, shared by `render`, `bench` and `reproduce`.
#[derive(Args)]
pub struct SimdArg {
    /// SIMD path of the hot code: auto (the fastest this CPU runs), portable, avx2 or
    /// avx512. Every path gives the same image; one the CPU lacks is refused.
    #[arg(
        long = "simd",
        env = "TESSERA_SIMD",
        default_value = "auto",
        value_name = "PATH"
    )]
    pub name: String,
}

impl SimdArg {
    /// The SIMD path `--simd` (or `TESSERA_SIMD`) names, if this CPU runs it.
    pub fn path(&self) -> Result<simd::Path> {
        simd::Path::choose(&self.name).map_err(|e| anyhow::anyhow!("--simd (or TESSERA_SIMD): {e}"))
    }

    /// Whether a path was named rather than left to `auto`.
    pub fn is_chosen(&self) -> bool {
        self.name != "auto"
    }
}

/// The results database's place, shared by `bench` and `results`.
#[derive(Args)]
pub struct DbArg {
    /// The results database [default: $XDG_DATA_HOME/tessera/results.db, else
    /// ~/.local/share/tessera/results.db].
    #[arg(long, global = true, env = "TESSERA_DB", value_name = "PATH")]
    pub db: Option<std::path::PathBuf>,
}

/// A whole number in `min..=max` typed as `text`.
fn whole(text: &str, min: u128, max: u128) -> Result<u128, String> {
    let trimmed = text.trim();
    let range = || format!("a whole number from {min} to {max}");
    match trimmed.parse::<i128>() {
        Ok(n) if n >= 0 && (min..=max).contains(&(n as u128)) => Ok(n as u128),
        Ok(_) => Err(format!("must be {}", range())),
        // More digits than an i128 holds: a number, but out of every range.
        Err(_)
            if !trimmed.is_empty()
                && trimmed
                    .trim_start_matches(['-', '+'])
                    .bytes()
                    .all(|b| b.is_ascii_digit()) =>
        {
            Err(format!("must be {}", range()))
        }
        Err(_) => Err(format!("`{}` is not {}", text.escape_debug(), range())),
    }
}

/// A count of at least 1 (a size, samples, depth, threads, a tile edge).
pub fn positive_u32(text: &str) -> Result<u32, String> {
    whole(text, 1, u128::from(u32::MAX)).map(|n| n as u32)
}

/// A count of 0 or more (warm-up renders, a limit of rows).
pub fn whole_u32(text: &str) -> Result<u32, String> {
    whole(text, 0, u128::from(u32::MAX)).map(|n| n as u32)
}

/// A thread count: 1 to 4096.
pub fn threads(text: &str) -> Result<usize, String> {
    whole(text, 1, 4096).map(|n| n as usize)
}

/// A thread count a recorded run may have (`results history --threads`): 1 to what an
/// import takes, which is more than a render may start.
#[cfg(feature = "results")]
pub fn recorded_threads(text: &str) -> Result<usize, String> {
    whole(text, 1, tessera::record::result::MAX_THREADS as u128).map(|n| n as usize)
}

/// A seed: any 64-bit unsigned number.
pub fn seed(text: &str) -> Result<u64, String> {
    whole(text, 0, u128::from(u64::MAX)).map(|n| n as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_out_of_range_say_the_range() {
        assert_eq!(positive_u32("16"), Ok(16));
        assert_eq!(positive_u32(" 7 "), Ok(7));
        assert_eq!(
            positive_u32("-5"),
            Err("must be a whole number from 1 to 4294967295".into())
        );
        assert_eq!(
            positive_u32("0"),
            Err("must be a whole number from 1 to 4294967295".into())
        );
        assert_eq!(
            seed("-1"),
            Err("must be a whole number from 0 to 18446744073709551615".into())
        );
        assert_eq!(seed("18446744073709551615"), Ok(u64::MAX));
        assert_eq!(
            seed("99999999999999999999999999999999999999999999"),
            Err("must be a whole number from 0 to 18446744073709551615".into())
        );
        assert_eq!(
            threads("two"),
            Err("`two` is not a whole number from 1 to 4096".into())
        );
        assert_eq!(whole_u32("0"), Ok(0));
    }

    #[test]
    #[cfg(feature = "results")]
    fn a_recorded_run_s_thread_count_is_chosen_up_to_what_an_import_takes() {
        // An imported run may have used more threads than a render here may start: `history`
        // still picks it out.
        assert_eq!(recorded_threads("8192"), Ok(8192));
        assert_eq!(recorded_threads("65536"), Ok(65536));
        assert_eq!(
            recorded_threads("65537"),
            Err("must be a whole number from 1 to 65536".into())
        );
        assert!(threads("8192").is_err());
    }
}
