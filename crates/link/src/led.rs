//! The three LEDs of the card, as the VACON OPTE3/E5 option board shows them (manual §4.3,
//! Tables 5–7), computed from the card's state and the time (sans-IO: the board drives pins,
//! the QEMU build logs changes).
//!
//! | LED | colour | off | on | blinking fast (1/s) | blinking slow (1/5 s) |
//! |---|---|---|---|---|---|
//! | PS, PROFIBUS status | red | DP communicates normally (data exchange) | communication broken or not started (no master, wrong configuration / parameters) | — | — |
//! | BS, board status | yellow | card not activated | waiting for the drive (no drive heartbeat yet) | activated, RUN | card FAULT |
//! | FS, fieldbus status | green | waiting for parameters from the drive | activated, waiting for bus messages | receiving messages addressed to us | FAULT: no message within the watchdog time after data exchange (bus broken, master offline) |

use crate::time::{Duration, Instant};

/// What one LED does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Led {
    /// Dark.
    Off,
    /// Lit.
    On,
    /// Once per second (0.5 s on, 0.5 s off).
    BlinkFast,
    /// Once per five seconds (0.5 s on, 4.5 s off).
    BlinkSlow,
}

impl Led {
    /// Whether the LED is lit at `now` (blinking phases count from the time origin).
    pub fn is_lit(self, now: Instant) -> bool {
        let ms = now.as_micros() / 1000;
        match self {
            Led::Off => false,
            Led::On => true,
            Led::BlinkFast => ms % 1000 < 500,
            Led::BlinkSlow => ms % 5000 < 500,
        }
    }
}

/// The card's state as the LEDs need it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LedInputs {
    /// The DP slave is in data exchange.
    pub data_exchange: bool,
    /// The drive has activated the card (its heartbeat or configuration arrived); a card
    /// without a supervised drive counts as activated.
    pub drive_active: bool,
    /// An internal card fault (panic recovery, DPM fault).
    pub card_fault: bool,
    /// The last telegram addressed to us, if any.
    pub last_frame_for_us: Option<Instant>,
    /// The DP watchdog time in force (`None`: off).
    pub watchdog: Option<Duration>,
    /// Data exchange was reached once and then lost (watchdog, master gone).
    pub lost_after_data_exchange: bool,
}

/// The three LEDs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Leds {
    /// PS, red: PROFIBUS status.
    pub ps: Led,
    /// BS, yellow: board status.
    pub bs: Led,
    /// FS, green: fieldbus status.
    pub fs: Led,
}

/// How recent a telegram must be for FS to show "receiving" when no DP watchdog is set.
pub const RECEIVING_WINDOW: Duration = Duration::from_millis(1000);

/// The LED pattern for `inputs` at `now` (OPTE3/E5 Tables 5–7).
pub fn indicate(now: Instant, inputs: &LedInputs) -> Leds {
    let ps = if inputs.data_exchange { Led::Off } else { Led::On };
    let bs = match (inputs.card_fault, inputs.drive_active) {
        (true, _) => Led::BlinkSlow,
        (false, true) => Led::BlinkFast,
        (false, false) => Led::On,
    };
    let window = inputs.watchdog.unwrap_or(RECEIVING_WINDOW);
    let receiving = inputs.last_frame_for_us.is_some_and(|t| now.saturating_since(t) <= window);
    let fs = if !inputs.drive_active {
        Led::Off
    } else if receiving {
        Led::BlinkFast
    } else if inputs.lost_after_data_exchange {
        Led::BlinkSlow
    } else {
        Led::On
    };
    Leds { ps, bs, fs }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    #[test]
    fn start_up_data_exchange_and_loss() {
        // Power on: the drive has not activated the card yet.
        let mut i = LedInputs::default();
        assert_eq!(indicate(at(0), &i), Leds { ps: Led::On, bs: Led::On, fs: Led::Off });
        // Drive active, no master yet.
        i.drive_active = true;
        assert_eq!(indicate(at(10), &i), Leds { ps: Led::On, bs: Led::BlinkFast, fs: Led::On });
        // Data exchange with telegrams for us.
        i.data_exchange = true;
        i.last_frame_for_us = Some(at(100));
        i.watchdog = Some(Duration::from_millis(200));
        assert_eq!(indicate(at(150), &i), Leds { ps: Led::Off, bs: Led::BlinkFast, fs: Led::BlinkFast });
        // Master gone: watchdog expired, data exchange left.
        i.data_exchange = false;
        i.lost_after_data_exchange = true;
        assert_eq!(indicate(at(400), &i), Leds { ps: Led::On, bs: Led::BlinkFast, fs: Led::BlinkSlow });
        // Card fault.
        i.card_fault = true;
        assert_eq!(indicate(at(400), &i).bs, Led::BlinkSlow);
    }

    #[test]
    fn blink_rates() {
        let lit = |l: Led, period_ms: u64| (0..period_ms).filter(|&t| l.is_lit(at(t))).count();
        assert_eq!(lit(Led::BlinkFast, 1000), 500);
        assert_eq!(lit(Led::BlinkSlow, 5000), 500);
        assert!(Led::On.is_lit(at(7)) && !Led::Off.is_lit(at(7)));
    }
}
