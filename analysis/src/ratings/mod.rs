//! Rating studies (`kind = "rating"`, ITU-T P.910 ACR, DCR and ACR-HR).
pub mod sureal;
#[cfg(test)]
mod sureal_tests;
