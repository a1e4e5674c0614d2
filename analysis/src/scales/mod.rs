//! The field's own scales beside Bradley–Terry: [`jod`] (pwcmp's just-objectionable
//! differences) and [`davidson`] (Bradley–Terry with ties, "not sure").

pub mod davidson;
pub mod jod;
