//! The HAL's errors by name, for the main task's log.
//!
//! embassy-stm32 is built without its `defmt` feature (firmware/Cargo.toml):
//! with it, each of its ≈ 40 panic and assertion sites carried a defmt log
//! call (≈ 0.7 KB of the image). The two HAL errors the main task logs are
//! named here instead; the names are in `.defmt`, not in flash.

/// A USART receive error.
#[derive(defmt::Format)]
pub enum UsartFault {
    Framing,
    Noise,
    Overrun,
    Parity,
    BufferTooLong,
    Other,
}

impl From<embassy_stm32::usart::Error> for UsartFault {
    fn from(e: embassy_stm32::usart::Error) -> Self {
        use embassy_stm32::usart::Error as E;
        #[allow(unreachable_patterns)]
        match e {
            E::Framing => Self::Framing,
            E::Noise => Self::Noise,
            E::Overrun => Self::Overrun,
            E::Parity => Self::Parity,
            E::BufferTooLong => Self::BufferTooLong,
            _ => Self::Other,
        }
    }
}

/// An FDCAN bus error.
#[derive(defmt::Format)]
pub enum CanFault {
    Stuff,
    Form,
    Acknowledge,
    BitRecessive,
    BitDominant,
    Crc,
    Other,
}

impl From<embassy_stm32::can::enums::BusError> for CanFault {
    fn from(e: embassy_stm32::can::enums::BusError) -> Self {
        use embassy_stm32::can::enums::BusError as E;
        #[allow(unreachable_patterns)]
        match e {
            E::Stuff => Self::Stuff,
            E::Form => Self::Form,
            E::Acknowledge => Self::Acknowledge,
            E::BitRecessive => Self::BitRecessive,
            E::BitDominant => Self::BitDominant,
            E::Crc => Self::Crc,
            _ => Self::Other,
        }
    }
}
