//! `tessera compare A B`: the difference of two images of equal size (PNG, PPM, EXR or
//! JPEG) as RMSE, PSNR and mean absolute error, on values in [0, 1].

use super::output::{out, significant};
use anyhow::Result;
use std::path::PathBuf;
use std::process::ExitCode;
use tessera::text::{path_safe, terminal_safe};

/// `tessera compare` as typed.
#[derive(clap::Args)]
pub struct Args {
    a: PathBuf,
    b: PathBuf,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let d = tessera::image_diff::difference_of_files(&args.a, &args.b)?;
    // The values measured are not all a viewer shows: a PNG's transparency, colour or
    // animation chunks, an EXR's thumbnail or aspect ratio, change the picture. Where a file
    // holds such, equal values are not called identical, and what it holds is listed.
    let psnr = if d.psnr_db.is_finite() {
        format!("{:.2} dB", d.psnr_db)
    } else if d.display_changes.is_empty() {
        "inf dB (identical)".to_owned()
    } else {
        "inf dB (the same values; what is listed below changes how one is shown)".to_owned()
    };
    let mut said = format!(
        "RMSE {}  PSNR {psnr}  mean abs error {}\n",
        significant(d.rmse, 4),
        significant(d.mean_abs, 4)
    );
    for (path, change) in &d.display_changes {
        said.push_str(&format!(
            "{}: {}\n",
            path_safe(path),
            terminal_safe(change, usize::MAX)
        ));
    }
    out(&said)?;
    Ok(ExitCode::SUCCESS)
}
