//! The two USARTs, 8N1: USART1 on PA9 (TX) and PA10 (RX), the host's line or a wired sensor's;
//! USART2 on PA2 (TX) and PA3 (RX), the line a sensor's map goes out on and a listener's
//! requests come in on. The receive interrupts' side and a polled transmitter.

use stm32f4::stm32f405 as pac;

use crate::clocks::Clocks;

/// Polls of the transmitter's empty flag before a byte is given up (a transmitter that never
/// empties is a fault, not a reason to hang): at 921,600 baud a byte takes 11 us, about 180
/// polls at 16 MHz.
const TX_POLLS: u32 = 100_000;

/// Which USART.
#[derive(Clone, Copy)]
pub enum Port {
    Usart1,
    Usart2,
}

/// What a receive interrupt found.
pub enum Received {
    Byte(u8),
    /// A byte, after one or more that the data register lost (the interrupt came too late).
    Overrun(u8),
    Nothing,
}

/// Clocks GPIOA and both USARTs, puts PA9/PA10 and PA2/PA3 on alternate function 7, and starts
/// each USART at `baud` from its bus clock (APB2 for USART1, APB1 for USART2), with the
/// receive interrupt on.
pub fn setup(rcc: &pac::RCC, gpioa: &pac::GPIOA, clocks: Clocks, baud: u32) {
    rcc.ahb1enr().modify(|_, w| w.gpioaen().set_bit());
    rcc.apb2enr().modify(|_, w| w.usart1en().set_bit());
    rcc.apb1enr().modify(|_, w| w.usart2en().set_bit());
    // SAFETY: MODER2/3 and MODER9/10 = 0b10 (alternate function), AFRL2/3 and AFRH9/10 = 7
    // (USART1 and USART2): RM0090 8.4.
    gpioa.moder().modify(|r, w| unsafe {
        w.bits((r.bits() & !((0b1111 << 18) | (0b1111 << 4))) | (0b1010 << 18) | (0b1010 << 4))
    });
    gpioa
        .afrh()
        .modify(|r, w| unsafe { w.bits((r.bits() & !(0xff << 4)) | (0x77 << 4)) });
    gpioa
        .afrl()
        .modify(|r, w| unsafe { w.bits((r.bits() & !(0xff << 8)) | (0x77 << 8)) });
    for (port, bus) in [(Port::Usart1, clocks.pclk2), (Port::Usart2, clocks.pclk1)] {
        let usart = registers(port);
        // Oversampling by 16: BRR is the bus clock over the baud rate, rounded.
        // SAFETY: BRR takes any 16-bit divisor; 84 MHz / 921,600 is 91, 42 MHz / 921,600 is
        // 46, 16 MHz / 921,600 is 17.
        let divisor = (bus + baud / 2) / baud.max(1);
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
}

fn registers(port: Port) -> &'static pac::usart1::RegisterBlock {
    // SAFETY: the USARTs' registers at their fixed addresses (USART2's block is USART1's
    // layout); each interrupt reads its own SR and DR, the main loop writes DR, and reading SR
    // then DR is how both flags are cleared (RM0090 30.6.1).
    unsafe {
        match port {
            Port::Usart1 => &*pac::USART1::ptr(),
            Port::Usart2 => &*pac::USART2::ptr(),
        }
    }
}

/// A receive interrupt's read: SR, then DR if it holds a byte (which clears RXNE and ORE).
pub fn receive(port: Port) -> Received {
    let usart = registers(port);
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

/// Sends `bytes` on `port`, each when the transmit register is empty.
pub fn send(port: Port, bytes: &[u8]) {
    let usart = registers(port);
    for &byte in bytes {
        if !(0..TX_POLLS).any(|_| usart.sr().read().txe().bit_is_set()) {
            return;
        }
        // SAFETY: DR takes a 9-bit value; a byte is one.
        usart.dr().write(|w| unsafe { w.bits(u16::from(byte)) });
    }
}

/// Waits, a bounded time, until the last byte has left `port`'s shift register (before a
/// reset).
pub fn flush(port: Port) {
    let usart = registers(port);
    let _ = (0..TX_POLLS).any(|_| usart.sr().read().tc().bit_is_set());
}
