//! Set_Slave_Add (SAP 55): a master changes the station address (reference §3.9).
//!
//! `New_Slave_Address, Ident_Hi, Ident_Lo, No_Add_Chg [, Rem_Slave_Data…]`. Accepted only
//! before parameterization (Wait_Prm) and while the address is not frozen; the new address
//! and the No_Add_Chg flag must survive a power cut, which is the job of an [`AddressStore`].

/// The highest address Set_Slave_Add (and the drive's `CONFIG.STATION_ADDRESS`) may set
/// (126 is only the commissioning default, reference §3.9).
pub const MAX_NEW_ADDRESS: u8 = 125;

/// Why a Set_Slave_Add was refused (answered RS).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum SlaveAddError {
    /// Fewer than 4 bytes or more than 244.
    Length,
    /// Address above 125.
    Address(u8),
    /// Ident number not ours.
    Ident(u16),
    /// The address was frozen by an earlier No_Add_Chg.
    Frozen,
    /// The slave is parameterized (not in Wait_Prm).
    State,
}

/// A checked Set_Slave_Add.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SetSlaveAdd {
    /// The new station address (0..=125).
    pub address: u8,
    /// No further address changes until a factory reset.
    pub no_add_chg: bool,
}

impl SetSlaveAdd {
    /// Parse and check the PDU (state checks are the slave's); `ident` is the product's GSD
    /// `Ident_Number` ([`super::SlaveConfig::ident_number`]), which the request must carry.
    pub fn parse(pdu: &[u8], ident_number: u16) -> Result<SetSlaveAdd, SlaveAddError> {
        if pdu.len() < 4 || pdu.len() > 244 {
            return Err(SlaveAddError::Length);
        }
        if pdu[0] > MAX_NEW_ADDRESS {
            return Err(SlaveAddError::Address(pdu[0]));
        }
        let ident = u16::from_be_bytes([pdu[1], pdu[2]]);
        if ident != ident_number {
            return Err(SlaveAddError::Ident(ident));
        }
        Ok(SetSlaveAdd { address: pdu[0], no_add_chg: pdu[3] != 0 })
    }
}

/// Non-volatile storage of the station address (flash journal on the board, a file in the
/// soft slave, memory in host tests). The DP slave reports an accepted Set_Slave_Add as
/// [`Events::ADDRESS_CHANGED`](super::Events::ADDRESS_CHANGED); the integration then calls
/// [`save`](AddressStore::save) outside the interrupt path.
pub trait AddressStore {
    /// Why a save failed.
    type Error;
    /// The stored address and No_Add_Chg flag, `None` after a factory reset / blank store.
    fn load(&mut self) -> Option<(u8, bool)>;
    /// Persist the address and flag so that a power cut at any point keeps either the old
    /// or the new pair.
    fn save(&mut self, address: u8, no_add_chg: bool) -> Result<(), Self::Error>;
}

/// An [`AddressStore`] in RAM (host tests).
#[derive(Debug, Default, Clone, Copy)]
pub struct MemoryStore {
    /// What was saved last.
    pub saved: Option<(u8, bool)>,
}

impl AddressStore for MemoryStore {
    type Error = core::convert::Infallible;
    fn load(&mut self) -> Option<(u8, bool)> {
        self.saved
    }
    fn save(&mut self, address: u8, no_add_chg: bool) -> Result<(), Self::Error> {
        self.saved = Some((address, no_add_chg));
        Ok(())
    }
}
