//! Which part of a render one process takes: shard specs (`I/N`, or the index from a job
//! system's environment), explicit sample ranges, and the job they make.

use crate::error::{Error, Result};
use crate::job::{Job, SampleRange};
use crate::math::PixelRect;
use crate::scene::Scene;

/// How shards divide a render.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Split {
    /// Every shard renders every pixel over its own slice of the sample indices. The work
    /// is even (each pixel costs the same in every slice) and each part is a whole image.
    #[default]
    Samples,
    /// Every shard renders a band of rows with all samples: smaller parts, uneven work.
    Rows,
}

/// Shard `index` of `count`, 0-based.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

fn setting(field: &str, message: impl Into<String>) -> Error {
    Error::Setting {
        field: field.to_owned(),
        message: message.into(),
    }
}

fn number(text: &str, field: &str, what: &str) -> Result<u32> {
    text.trim().parse().map_err(|_| {
        setting(
            field,
            format!("{what} `{text}` is not a non-negative integer"),
        )
    })
}

impl Shard {
    /// Parses `I/N`, `env` or `env/N`. `env` takes the index from the job system:
    /// `SLURM_ARRAY_TASK_ID` (less `SLURM_ARRAY_TASK_MIN`) with the count from
    /// `SLURM_ARRAY_TASK_COUNT`, or Kubernetes' `JOB_COMPLETION_INDEX` with the count given
    /// as `env/N`. `var` looks up environment variables.
    pub fn parse(spec: &str, var: impl Fn(&str) -> Option<String>) -> Result<Shard> {
        let field = "--shard";
        let (index_text, count_text) = match spec.split_once('/') {
            Some((i, n)) => (i.trim(), Some(n.trim())),
            None => (spec.trim(), None),
        };
        let (index, count) = if index_text == "env" {
            let slurm = var("SLURM_ARRAY_TASK_ID");
            let (index, from) = match (&slurm, var("JOB_COMPLETION_INDEX")) {
                (Some(id), _) => {
                    let id = number(id, field, "SLURM_ARRAY_TASK_ID")?;
                    let min = match var("SLURM_ARRAY_TASK_MIN") {
                        Some(m) => number(&m, field, "SLURM_ARRAY_TASK_MIN")?,
                        None => 0,
                    };
                    let index = id.checked_sub(min).ok_or_else(|| {
                        setting(
                            field,
                            format!("SLURM_ARRAY_TASK_ID {id} is below SLURM_ARRAY_TASK_MIN {min}"),
                        )
                    })?;
                    (index, "SLURM_ARRAY_TASK_ID")
                }
                (None, Some(i)) => (
                    number(&i, field, "JOB_COMPLETION_INDEX")?,
                    "JOB_COMPLETION_INDEX",
                ),
                (None, None) => {
                    return Err(setting(
                        field,
                        "`env` needs SLURM_ARRAY_TASK_ID (a Slurm array job) or \
                         JOB_COMPLETION_INDEX (a Kubernetes Indexed Job) in the environment",
                    ));
                }
            };
            let count = match (count_text, var("SLURM_ARRAY_TASK_COUNT")) {
                (Some(n), _) => number(n, field, "shard count")?,
                (None, Some(n)) if slurm.is_some() => number(&n, field, "SLURM_ARRAY_TASK_COUNT")?,
                _ => {
                    return Err(setting(
                        field,
                        format!("the index comes from {from}; give the shard count as `env/N`"),
                    ));
                }
            };
            (index, count)
        } else {
            let Some(n) = count_text else {
                return Err(setting(
                    field,
                    format!("`{spec}` is not `I/N`, `env` or `env/N`"),
                ));
            };
            (
                number(index_text, field, "shard index")?,
                number(n, field, "shard count")?,
            )
        };
        if count == 0 || index >= count {
            return Err(setting(
                field,
                format!(
                    "shard index {index} is not below the shard count {count} (indices start at 0)"
                ),
            ));
        }
        Ok(Shard { index, count })
    }

    /// The `index`-th of `count` near-equal slices of `start..end`.
    fn slice(&self, start: u32, end: u32) -> (u32, u32) {
        let len = u64::from(end - start);
        let at = |i: u32| start + (len * u64::from(i) / u64::from(self.count)) as u32;
        (at(self.index), at(self.index + 1))
    }
}

/// Parses a sample range `A..B` (A < B).
pub fn parse_samples(text: &str) -> Result<SampleRange> {
    let field = "--samples";
    let Some((a, b)) = text.split_once("..") else {
        return Err(setting(field, format!("`{text}` is not a range `A..B`")));
    };
    let start = number(a, field, "start")?;
    let end = number(b, field, "end")?;
    if start >= end {
        return Err(setting(
            field,
            format!("`{text}` is empty: the start must be below the end"),
        ));
    }
    Ok(SampleRange { start, end })
}

/// The job one process renders: the scene's window over `samples` (default all of the
/// scene's samples), narrowed to one shard if there is one.
pub fn job(
    scene: &Scene,
    shard: Option<Shard>,
    split: Split,
    samples: Option<SampleRange>,
) -> Result<Job> {
    let window = scene.settings.window;
    let samples = samples.unwrap_or(SampleRange {
        start: 0,
        end: scene.settings.samples_per_pixel,
    });
    let Some(shard) = shard else {
        return Ok(Job {
            region: window,
            samples,
        });
    };
    let job = match split {
        Split::Samples => {
            if shard.count > samples.len() {
                return Err(setting(
                    "--shard",
                    format!(
                        "{} shards cannot split {} samples per pixel",
                        shard.count,
                        samples.len()
                    ),
                ));
            }
            let (start, end) = shard.slice(samples.start, samples.end);
            Job {
                region: window,
                samples: SampleRange { start, end },
            }
        }
        Split::Rows => {
            if shard.count > window.height {
                return Err(setting(
                    "--shard",
                    format!("{} shards cannot split {} rows", shard.count, window.height),
                ));
            }
            let (y0, y1) = shard.slice(window.y0, window.y0 + window.height);
            Job {
                region: PixelRect {
                    x0: window.x0,
                    y0,
                    width: window.width,
                    height: y1 - y0,
                },
                samples,
            }
        }
    };
    Ok(job)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: Vec<(String, String)> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |k| map.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone())
    }

    #[test]
    fn explicit_shards() {
        assert_eq!(
            Shard::parse("2/4", env(&[])).unwrap(),
            Shard { index: 2, count: 4 }
        );
        assert!(Shard::parse("4/4", env(&[])).is_err());
        assert!(Shard::parse("1/0", env(&[])).is_err());
        assert!(Shard::parse("x/3", env(&[])).is_err());
        assert!(Shard::parse("3", env(&[])).is_err());
    }

    #[test]
    fn shards_from_slurm_and_kubernetes() {
        let slurm = env(&[
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
        ]);
        assert_eq!(
            Shard::parse("env", slurm).unwrap(),
            Shard { index: 4, count: 8 }
        );
        let k8s = env(&[("JOB_COMPLETION_INDEX", "3")]);
        assert_eq!(
            Shard::parse("env/6", &k8s).unwrap(),
            Shard { index: 3, count: 6 }
        );
        assert!(
            Shard::parse("env", &k8s)
                .unwrap_err()
                .to_string()
                .contains("env/N")
        );
        assert!(
            Shard::parse("env", env(&[]))
                .unwrap_err()
                .to_string()
                .contains("SLURM_ARRAY_TASK_ID")
        );
    }

    #[test]
    fn slices_partition_the_range() {
        for count in 1..9 {
            let mut next = 3;
            for index in 0..count {
                let (a, b) = Shard { index, count }.slice(3, 20);
                assert_eq!(a, next);
                next = b;
            }
            assert_eq!(next, 20);
        }
    }

    #[test]
    fn sample_ranges() {
        assert_eq!(
            parse_samples("4..9").unwrap(),
            SampleRange { start: 4, end: 9 }
        );
        assert!(parse_samples("9..4").is_err());
        assert!(parse_samples("4-9").is_err());
    }
}
