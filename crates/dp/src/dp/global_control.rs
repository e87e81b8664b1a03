//! Global_Control (SAP 58, SDN, usually broadcast): Clear_Data, Sync/Unsync,
//! Freeze/Unfreeze with group selection (reference §3.6).

bitflags::bitflags! {
    /// Control_Command (Global_Control byte 0).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct ControlCommand: u8 {
        /// b1 Clear_Data: the master is in Clear; outputs go to the safe state.
        const CLEAR_DATA = 0x02;
        /// b2 Unfreeze.
        const UNFREEZE = 0x04;
        /// b3 Freeze: sample inputs now and keep them until the next Freeze.
        const FREEZE = 0x08;
        /// b4 Unsync.
        const UNSYNC = 0x10;
        /// b5 Sync: apply the last outputs now and hold later ones until the next Sync.
        const SYNC = 0x20;
    }
}

/// A parsed Global_Control.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GlobalControl {
    /// Control_Command (reserved bits b0, b6, b7 dropped).
    pub command: ControlCommand,
    /// Reserved command bits that were set (counted, otherwise ignored).
    pub reserved: u8,
    /// Group_Select: 0 = all slaves.
    pub group_select: u8,
}

impl GlobalControl {
    /// Parse the 2-byte PDU; `None` when the length is not 2.
    pub fn parse(pdu: &[u8]) -> Option<GlobalControl> {
        match *pdu {
            [cmd, group_select] => Some(GlobalControl {
                command: ControlCommand::from_bits_truncate(cmd),
                reserved: cmd & 0xC1,
                group_select,
            }),
            _ => None,
        }
    }

    /// Whether a slave with `group_ident` processes this command.
    pub fn selects(&self, group_ident: u8) -> bool {
        self.group_select == 0 || self.group_select & group_ident != 0
    }
}
