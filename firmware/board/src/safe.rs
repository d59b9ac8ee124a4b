//! The front panel, and the safe state a panic leaves the board in.
//!
//! Both images are fail-silent: after a panic nothing the program computed can be trusted, so
//! the board sends nothing more. Every controller aborts what waits in its mailboxes and enters
//! initialisation mode (its transmit pin recessive: the board is off the buses), the panel
//! shows the fault, and the processor stops. What the other nodes do then is theirs, by design:
//! an SRDO consumer reaches its safe state when the refresh time passes without a valid SRDO, a
//! heartbeat consumer reports the board lost, a standby master takes over.

use crate::hal::gpio::{Output, Pin, PushPull};
use crate::hal::pac::{CAN1, CAN2, CAN3, GPIOB};

/// The panel's LEDs (NUCLEO-F413ZH: LD1 green on PB0, LD2 blue on PB7, LD3 red on PB14).
pub struct Panel {
    green: Pin<'B', 0, Output<PushPull>>,
    blue: Pin<'B', 7, Output<PushPull>>,
    red: Pin<'B', 14, Output<PushPull>>,
}

impl Panel {
    /// The LEDs, all off.
    pub fn new(
        green: Pin<'B', 0, Output<PushPull>>,
        blue: Pin<'B', 7, Output<PushPull>>,
        red: Pin<'B', 14, Output<PushPull>>,
    ) -> Panel {
        let mut p = Panel { green, blue, red };
        p.show(false, false);
        p.red.set_low();
        p
    }

    /// Green: the board does its job (gateway operational, master active); blue: both buses
    /// carry traffic.
    pub fn show(&mut self, running: bool, buses_ok: bool) {
        self.green.set_state(running.into());
        self.blue.set_state(buses_ok.into());
    }
}

/// Puts the board into its safe state and stops there (see the module docs): the panic
/// handlers of both images end here.
pub fn fail_silent() -> ! {
    cortex_m::interrupt::disable();
    // SAFETY: a panic has ended the program: nothing else touches these registers from here
    // on (interrupts are off and no handler exists), and the writes only request what the
    // reference manual allows at any time (abort a transmission, enter initialisation). A
    // controller whose clock was never enabled ignores them.
    #[allow(unsafe_code)]
    let (cans, gpiob) = unsafe {
        (
            [&*CAN1::ptr(), &*CAN2::ptr(), &*CAN3::ptr()],
            &*GPIOB::ptr(),
        )
    };
    for can in cans {
        can.tsr()
            .write(|w| w.abrq0().set_bit().abrq1().set_bit().abrq2().set_bit());
        can.mcr().modify(|_, w| w.inrq().set_bit());
    }
    // Red on, green and blue off, in one write.
    gpiob
        .bsrr()
        .write(|w| w.bs14().set_bit().br0().set_bit().br7().set_bit());
    loop {
        cortex_m::asm::wfi();
    }
}
