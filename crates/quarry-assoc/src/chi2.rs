//! Chi-square quantiles for any number of degrees of freedom: re-exported from
//! [`quarry_core::stats`], where quarry-eval's NEES consistency test shares them.

pub use quarry_core::stats::{chi2_cdf, chi2_quantile, gamma_p, ln_gamma};
