//! What a benchmark records, below both `bench` (which makes records) and `results` (which
//! reads them): the result and its schema (`result`), the build and host it ran on
//! (`host`), the workloads (`workload`), one measurement (`measure`), measurements pooled
//! over runs (`stats`), and the SQLite database that keeps them (`db`, with `results`).

#[cfg(feature = "results")]
pub mod db;
pub mod host;
pub mod measure;
pub mod result;
pub mod stats;
pub mod unique_json;
pub mod workload;
