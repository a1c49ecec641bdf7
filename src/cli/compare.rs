//! `tessera compare A B`: the difference of two images of equal size (PNG, PPM, EXR or
//! JPEG) as RMSE, PSNR and mean absolute error, on values in [0, 1].

use super::output::{out, significant};
use anyhow::Result;
use std::path::PathBuf;
use std::process::ExitCode;

/// `tessera compare` as typed.
#[derive(clap::Args)]
pub struct Args {
    a: PathBuf,
    b: PathBuf,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let d = tessera::image_diff::difference_of_files(&args.a, &args.b)?;
    let psnr = if d.psnr_db.is_finite() {
        format!("{:.2} dB", d.psnr_db)
    } else {
        "inf dB (identical)".to_owned()
    };
    out(&format!(
        "RMSE {}  PSNR {psnr}  mean abs error {}\n",
        significant(d.rmse, 4),
        significant(d.mean_abs, 4)
    ))?;
    Ok(ExitCode::SUCCESS)
}
