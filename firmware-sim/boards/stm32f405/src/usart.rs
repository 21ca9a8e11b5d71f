//! USART1 on PA9 (TX) and PA10 (RX), 8N1: the receive interrupt's side and a polled transmitter.

use stm32f4::stm32f405 as pac;

/// Polls of the transmitter's empty flag before a byte is given up (a transmitter that never
/// empties is a fault, not a reason to hang): at 921,600 baud a byte takes 11 us, about 180
/// polls at 16 MHz.
const TX_POLLS: u32 = 100_000;

/// What the receive interrupt found.
pub enum Received {
    Byte(u8),
    /// A byte, after one or more that the data register lost (the interrupt came too late).
    Overrun(u8),
    Nothing,
}

/// Clocks GPIOA and USART1, puts PA9/PA10 on alternate function 7, and starts the USART at
/// `baud` from its bus clock `pclk2`, with the receive interrupt on.
pub fn setup(rcc: &pac::RCC, gpioa: &pac::GPIOA, usart: pac::USART1, pclk2: u32, baud: u32) {
    rcc.ahb1enr().modify(|_, w| w.gpioaen().set_bit());
    rcc.apb2enr().modify(|_, w| w.usart1en().set_bit());
    // SAFETY: MODER9/10 = 0b10 (alternate function), AFRH9/10 = 7 (USART1): RM0090 8.4.
    gpioa
        .moder()
        .modify(|r, w| unsafe { w.bits((r.bits() & !(0b1111 << 18)) | (0b1010 << 18)) });
    gpioa
        .afrh()
        .modify(|r, w| unsafe { w.bits((r.bits() & !(0xff << 4)) | (0x77 << 4)) });
    // Oversampling by 16: BRR is the bus clock over the baud rate, rounded.
    // SAFETY: BRR takes any 16-bit divisor; 84 MHz / 921,600 is 91, 16 MHz / 921,600 is 17.
    let divisor = (pclk2 + baud / 2) / baud;
    usart
        .brr()
        .write(|w| unsafe { w.bits((divisor & 0xffff) as u16) });
    usart.cr1().write(|w| {
        w.ue()
            .set_bit()
            .te()
            .set_bit()
            .re()
            .set_bit()
            .rxneie()
            .set_bit()
    });
}

fn usart1() -> &'static pac::usart1::RegisterBlock {
    // SAFETY: USART1's registers at their fixed address; the interrupt reads SR and DR, the
    // main loop writes DR only after the stream is over, and reading SR then DR is how both
    // flags are cleared (RM0090 30.6.1).
    unsafe { &*pac::USART1::ptr() }
}

/// The receive interrupt's read: SR, then DR if it holds a byte (which clears RXNE and ORE).
pub fn receive() -> Received {
    let usart = usart1();
    let sr = usart.sr().read();
    if sr.rxne().bit_is_set() || sr.ore().bit_is_set() {
        let byte = usart.dr().read().bits() as u8;
        if sr.ore().bit_is_set() {
            Received::Overrun(byte)
        } else {
            Received::Byte(byte)
        }
    } else {
        Received::Nothing
    }
}

/// Sends `bytes`, each when the transmit register is empty.
pub fn send(bytes: &[u8]) {
    let usart = usart1();
    for &byte in bytes {
        if !(0..TX_POLLS).any(|_| usart.sr().read().txe().bit_is_set()) {
            return;
        }
        // SAFETY: DR takes a 9-bit value; a byte is one.
        usart.dr().write(|w| unsafe { w.bits(u16::from(byte)) });
    }
}

/// Waits, a bounded time, until the last byte has left the shift register (before a reset).
pub fn flush() {
    let usart = usart1();
    let _ = (0..TX_POLLS).any(|_| usart.sr().read().tc().bit_is_set());
}
