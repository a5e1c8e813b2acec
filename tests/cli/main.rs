//! The tests of the `tutti` command line, as a user runs it: one test binary with a module
//! per subject (`cargo test --test cli gateway_interop::`), instead of a binary per subject
//! each linking the workspace. What the tests share (child processes with a watchdog, the
//! `tutti` runner, namespaces, the venv, the policy for missing tools) is in the
//! `tutti-test-support` crate; their fixtures stay in `tests/<subject>/` (`tests/ddf-invalid`,
//! `tests/gateway/*.py`, `tests/fmu/c`, …).
//!
//! Tests of a library's own behaviour live in that crate's `tests/`.

// Helpers of the gateway tests, and `per_engine!`.
#[macro_use]
mod gateway;

mod bench_scale;
mod checkpoint;
mod connect;
mod ctl;
mod ddf_invalid;
mod ddf_valid;
mod doc_commands;
mod event;
mod fmu_errors;
mod fmu_exchange;
mod fmu_fmi3;
mod fmu_run;
mod gateway_churn;
mod gateway_citizen;
mod gateway_config;
mod gateway_event;
mod gateway_fastdds;
mod gateway_foxglove;
mod gateway_in_process;
mod gateway_interop;
mod gateway_mirror;
mod gateway_reliable;
mod gateway_security;
mod gateway_simif;
mod gateway_zenoh;
mod host_cli;
mod hostile_files;
mod idl_generated;
mod idl_tools;
mod install;
mod package;
mod record_mcap;
mod replay;
mod ros2_real;
mod ros2_typehash;
mod run;
mod simif_client;
mod ssp;
mod studio_browser;
mod uav_demo;
