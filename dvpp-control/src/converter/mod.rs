//! The converter interface of a DER at EMT level: frames, PI loops, the PLL, the filter and its inner loops.
//!
//! The paper's DERs are averaged three-phase voltage-source converters with a dc link, an RLC
//! filter and an LV/MV transformer ("Converter Interface of DERs"); the matching control of a
//! grid-forming unit closes cascaded voltage and current loops around the filter in the unit's
//! dq frame (option A). This module holds those parts, written for a controller that an EMT tool
//! samples every 20-50 µs:
//!
//! - [`frame`]: the amplitude-invariant Park transform between instantaneous three-phase values
//!   and the dq frame;
//! - [`pi`]: a sampled PI controller with output limits and anti-windup;
//! - [`pll`]: the synchronous-reference-frame PLL of grid-following units;
//! - [`filter`]: the paper's converter data and the filter's linear dq model (resonances, exact
//!   discretization), the model the loops are designed on;
//! - [`inner`]: the cascaded filter-voltage and converter-current loops, their gains designed
//!   from the filter data for chosen bandwidths, with current limiting.
//!
//! Per unit on the converter's rating: voltages on the rated phase-to-neutral peak voltage
//! `v_r`, currents on the rated peak current, so that with the amplitude-invariant transform
//! `p = v_d i_d + v_q i_q` and `q = v_q i_d - v_d i_q`; impedances on `v_r²/S_r`'s equivalent,
//! inductances and capacitances as reactance and susceptance at the base frequency `ω_b`
//! (`L di/dt = ω_b (…)` in seconds). Angles in radians, frequencies in pu of `ω_b`.

pub mod filter;
pub mod frame;
pub mod inner;
pub mod pi;
pub mod pll;

pub use filter::{ConverterData, Lcl};
pub use frame::{Abc, Dq};
pub use inner::{FilterMeasurement, InnerDesign, InnerLoops};
pub use pi::Pi;
pub use pll::Pll;
