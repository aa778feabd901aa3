//! Sensor frames found, not assumed: a gyro or magnetometer axis recorded in the wrong
//! order or sign, or the photodiode table written in another frame, named from the data
//! before the filter runs.
//!
//! The data say which frame is right without any attitude. The Sun and the Earth's field
//! are (nearly) fixed in the inertial frame, so both turn in the body frame as the gyro
//! says (`dv_B/dt = -w x v_B`), and the angle between them does not depend on the body
//! frame at all: it is the angle between the Sun and IGRF's field at the spacecraft. A
//! wrong signed permutation of one sensor's axes breaks these relations far beyond the
//! noise; the right one restores them. Three checks, each between two sensors:
//!
//! - gyro and magnetometer: the field direction carried from one row to the next by the
//!   gyro's rotation (less a bias fitted with it) against the next row's;
//! - gyro and photodiodes: the same with the Sun direction the photodiodes give;
//! - magnetometer and photodiodes: the cosine of the angle between the two measured
//!   directions against the reference's.
//!
//! Every one of the 48 signed permutations of one sensor's axes (the others as stated) is
//! a hypothesis, the stated axes the null ([`check`]). Each check's residuals are scored
//! with a Cauchy likelihood at the check's own robust scale (the best hypothesis's median
//! absolute residual), so that samples no model explains (albedo in the Sun direction,
//! the field's own turn along the orbit) weigh as outliers, not as evidence. A finding
//! needs decisive odds against the stated axes and against every other hypothesis
//! ([`Thresholds`]); where the data cannot decide, the result says so.
//!
//! Two sensors alone cannot say which of them is wrong; with the photodiodes and the gyro
//! only, the photodiode table defines the body frame and the gyro is checked against it.
//! The gyro-magnetometer check cannot see a proper rotation common to both; the
//! photodiodes' checks can.

mod check;
mod kinematics;
mod permutation;
mod sun;

pub use check::{
    AxesCheck, CheckCount, Evidence, Finding, Inputs, NotChecked, Sensor, Thresholds, check,
};
pub use permutation::{SIGNED_PERMUTATIONS, signed_permutations};
pub use sun::photodiode_sun;
