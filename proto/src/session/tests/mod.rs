//! Tests of the session cores: whole-cluster scenarios on virtual time and
//! direct message-by-message checks.

use crate::session::MasterConfig;

mod cluster;
mod direct;
mod fuzz;
mod illumination;

const MS: u64 = 1_000_000;
/// 120 Hz.
const PERIOD: u64 = 8_333_333;

pub(super) fn config(deadline_ms: u64) -> MasterConfig {
    MasterConfig {
        target_hz: 120.0,
        deadline_ns: deadline_ms * MS,
        ..MasterConfig::default()
    }
}
