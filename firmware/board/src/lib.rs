//! # The board both firmware images run on
//!
//! An STM32F413 (Cortex-M4F at 96 MHz, three bxCAN controllers, 1.5 MiB of flash, 320 KiB of
//! SRAM; the NUCLEO-F413ZH board is one), through the `stm32f4xx-hal` and `bxcan` crates:
//!
//! | What | Where |
//! | --- | --- |
//! | bus 1 | CAN1: PD0 receive, PD1 transmit |
//! | bus 2 | CAN2: PB12 receive, PB13 transmit |
//! | field bus (the gateway's) | CAN3: PA8 receive, PA15 transmit |
//! | clock | TIM2, 1 µs, free-running ([`clock`]) |
//! | panel | LD1 green, LD2 blue, LD3 red ([`safe::Panel`]) |
//! | computer strap (the master's) | PF12, pulled down: low is computer 1, high computer 2 |
//!
//! The main loop of both images is the same: acknowledge what woke it, read the clock, poll
//! the application (whose inner loop is duocan's `EmbeddedDriver`), arm the timer for the
//! deadline it returns, and sleep until a frame arrives, a mailbox frees or the deadline comes
//! ([`sleep`]). There is no interrupt handler and no busy-waiting but the hardware's own:
//! clock and PLL start-up, and the CAN controllers entering and leaving their configuration.
#![no_std]

pub mod can;
pub mod clock;
pub mod safe;
pub mod sleep;

pub use stm32f4xx_hal as hal;

use can::Port;
use clock::Clock;
use duocan::Instant;
use hal::pac;
use hal::prelude::*;
use hal::rcc::Config;
use safe::Panel;
use sleep::Sleep;

/// The HSE crystal (NUCLEO boards: the ST-LINK's 8 MHz clock output, hence bypass).
const HSE_HZ: u32 = 8_000_000;
/// The APB1 clock the CAN controllers run from.
pub const PCLK1_HZ: u32 = 48_000_000;

/// What the main loop runs: an image's application.
pub trait App {
    /// Acknowledges the controllers' wake-ups ([`Port::acknowledge`] on each), before a pass.
    fn acknowledge(&mut self);
    /// Does everything due at `now` and shows the state on `panel`; returns the next
    /// deadline (`None`: only a frame or a free mailbox brings work).
    fn poll(&mut self, now: Instant, panel: &mut Panel) -> Option<Instant>;
}

/// The board's clock, sleep and panel: what the main loop needs besides the application.
pub struct Board {
    clock: Clock,
    sleep: Sleep,
    panel: Panel,
    strap: bool,
}

/// The CAN controllers, for the application to own.
pub struct Ports {
    /// CAN1 and CAN2: bus 1 and bus 2.
    pub buses: [Port; 2],
    /// CAN3, if asked for: the gateway's field bus.
    pub field: Option<Port>,
}

/// Brings the board up: clocks (HSE, PLL to 96 MHz), timer, panel, strap, the CAN
/// controllers at [`can::BIT_RATE`] (CAN3 only with `field_bus`). `None` if called twice.
pub fn init(field_bus: bool) -> Option<(Board, Ports)> {
    let cp = cortex_m::Peripherals::take()?;
    let dp = pac::Peripherals::take()?;
    let mut rcc = dp.RCC.freeze(
        Config::hse(HSE_HZ.Hz())
            .bypass_hse_oscillator()
            .sysclk(96.MHz())
            .pclk1(PCLK1_HZ.Hz()),
    );
    let btr = can::bit_timing(rcc.clocks.pclk1().raw(), can::BIT_RATE)?;
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpiod = dp.GPIOD.split(&mut rcc);
    let gpiof = dp.GPIOF.split(&mut rcc);
    let panel = Panel::new(
        gpiob.pb0.into_push_pull_output(),
        gpiob.pb7.into_push_pull_output(),
        gpiob.pb14.into_push_pull_output(),
    );
    let strap = gpiof.pf12.into_pull_down_input().is_high();
    let can1 = dp.CAN1.can((gpiod.pd1, gpiod.pd0), &mut rcc);
    let can2 = dp.CAN2.can((gpiob.pb13, gpiob.pb12), &mut rcc);
    let buses = Port::dual(can1, can2, btr);
    // PA15 is the JTAG TDI pin after reset (the board is debugged over SWD).
    let field = field_bus.then(|| {
        let pins = (gpioa.pa15.into_input(), gpioa.pa8);
        Port::third(dp.CAN3.can(pins, &mut rcc), btr)
    });
    let board = Board {
        clock: Clock::start(dp.TIM2, &mut rcc),
        sleep: Sleep::new(cp.SCB),
        panel,
        strap,
    };
    Some((board, Ports { buses, field }))
}

impl Board {
    /// The computer strap: `false` computer 1, `true` computer 2.
    pub fn strap(&self) -> bool {
        self.strap
    }
    /// The current time.
    pub fn now(&mut self) -> Instant {
        self.clock.now()
    }

    /// The main loop: polls `app` whenever it has work, sleeps in between.
    pub fn run(mut self, app: &mut impl App) -> ! {
        loop {
            // What woke the processor is acknowledged before the poll, so that anything
            // from here on wakes the next wait.
            self.clock.acknowledge();
            app.acknowledge();
            self.sleep.rearm();
            let now = self.clock.now();
            let next = app.poll(now, &mut self.panel);
            if !self.clock.wake_at(next) {
                self.sleep.wait();
            }
        }
    }
}
