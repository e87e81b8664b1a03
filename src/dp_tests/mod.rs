//! The tests of the DP layer (the crate `pbcard-dp`, re-exported as [`crate::dp`]) with this
//! card's configuration: its module table, User_Prm_Data and Chk_Cfg policy ([`crate::card`])
//! and the scripted master's Set_Prm ([`crate::testkit`]). They are here, not beside the code,
//! because `pbcard-dp` cannot depend on the product; its own unit tests (`crates/dp`) cover
//! what needs no product.

mod cfg;
mod prm;
mod slave;
