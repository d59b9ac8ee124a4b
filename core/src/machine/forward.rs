//! Forwarding a machine's methods to the one inside or behind it, written once: wrappers
//! that only turn events into their own, or add to the link below, name the methods they do
//! not change instead of writing each out again.

use super::Device;

/// Inside `impl Device for T`: every method but `poll_event` (and the associated type) is
/// the one of the device in `T`'s field (`forward_device_to!(inner)`), or of the device behind
/// the pointer `T` is (`forward_device_to!(*)`). For a wrapper that only turns the inner
/// device's events into its own.
#[doc(hidden)]
#[macro_export]
macro_rules! forward_device_to {
    (@to $s:ident, *) => { (**$s) };
    (@to $s:ident, $field:tt) => { $s.$field };
    ($to:tt) => {
        fn port_count(&self) -> usize {
            $crate::forward_device_to!(@to self, $to).port_count()
        }
        fn handle_rx(&mut self, now: $crate::Instant, port: usize, frame: &$crate::Frame) {
            $crate::forward_device_to!(@to self, $to).handle_rx(now, port, frame);
        }
        fn handle_rx_at(
            &mut self,
            now: $crate::Instant,
            port: usize,
            frame: &$crate::Frame,
            at: $crate::Instant,
        ) {
            $crate::forward_device_to!(@to self, $to).handle_rx_at(now, port, frame, at);
        }
        fn handle_port_status(
            &mut self,
            now: $crate::Instant,
            port: usize,
            status: $crate::machine::PortStatus,
        ) {
            $crate::forward_device_to!(@to self, $to).handle_port_status(now, port, status);
        }
        fn handle_timeout(&mut self, now: $crate::Instant) {
            $crate::forward_device_to!(@to self, $to).handle_timeout(now);
        }
        fn poll_transmit(&mut self) -> Option<(usize, $crate::Frame)> {
            $crate::forward_device_to!(@to self, $to).poll_transmit()
        }
        fn poll_port_request(&mut self) -> Option<(usize, $crate::machine::PortRequest)> {
            $crate::forward_device_to!(@to self, $to).poll_port_request()
        }
        fn poll_timeout(&self) -> Option<$crate::Instant> {
            $crate::forward_device_to!(@to self, $to).poll_timeout()
        }
    };
}

/// Inside `impl BusLink for T`: the [`BusLink`] methods named are those of the link in `T`'s
/// field (`forward_bus_link!(bus; port_count, handle_rx)`), or of the link behind the pointer
/// `T` is (`forward_bus_link!(*; …)`). With `before = hook`, the methods that take the time
/// call `self.hook(now)` first (a wrapper that keeps the latest instant). For a wrapper that
/// only adds to the link below, so that the methods it does not change are written once here.
///
/// `fd` names the four CAN FD methods at once (`fd_capable`, `handle_rx_fd`, `send_fd`,
/// `poll_transmit_fd`), each under `#[cfg(feature = "fd")]`: that is the feature of the crate
/// the macro expands in, so name `fd` only in a crate whose `fd` feature turns on
/// `duocan-core/fd`.
#[doc(hidden)]
#[macro_export]
macro_rules! forward_bus_link {
    ($to:tt; $($method:ident),* $(,)?) => {
        $( $crate::forward_bus_link!(@one $method, $to, []); )*
    };
    ($to:tt, before = $hook:ident; $($method:ident),* $(,)?) => {
        $( $crate::forward_bus_link!(@one $method, $to, [$hook]); )*
    };
    (@to $s:ident, *) => { (**$s) };
    (@to $s:ident, $field:tt) => { $s.$field };
    (@one port_count, $to:tt, [$($hook:ident)?]) => {
        fn port_count(&self) -> usize {
            $crate::forward_bus_link!(@to self, $to).port_count()
        }
    };
    (@one handle_rx, $to:tt, [$($hook:ident)?]) => {
        fn handle_rx(
            &mut self,
            now: $crate::Instant,
            port: usize,
            frame: &$crate::Frame,
        ) -> Option<$crate::Frame> {
            $(self.$hook(now);)?
            $crate::forward_bus_link!(@to self, $to).handle_rx(now, port, frame)
        }
    };
    (@one handle_rx_at, $to:tt, [$($hook:ident)?]) => {
        fn handle_rx_at(
            &mut self,
            now: $crate::Instant,
            port: usize,
            frame: &$crate::Frame,
            at: $crate::Instant,
        ) -> Option<$crate::Frame> {
            $(self.$hook(now);)?
            $crate::forward_bus_link!(@to self, $to).handle_rx_at(now, port, frame, at)
        }
    };
    (@one handle_port_status, $to:tt, [$($hook:ident)?]) => {
        fn handle_port_status(
            &mut self,
            now: $crate::Instant,
            port: usize,
            status: $crate::machine::PortStatus,
        ) {
            $(self.$hook(now);)?
            $crate::forward_bus_link!(@to self, $to).handle_port_status(now, port, status);
        }
    };
    (@one send, $to:tt, [$($hook:ident)?]) => {
        fn send(&mut self, now: $crate::Instant, frame: &$crate::Frame) {
            $(self.$hook(now);)?
            $crate::forward_bus_link!(@to self, $to).send(now, frame);
        }
    };
    (@one poll_transmit, $to:tt, [$($hook:ident)?]) => {
        fn poll_transmit(&mut self) -> Option<(usize, $crate::Frame)> {
            $crate::forward_bus_link!(@to self, $to).poll_transmit()
        }
    };
    (@one poll_port_request, $to:tt, [$($hook:ident)?]) => {
        fn poll_port_request(&mut self) -> Option<(usize, $crate::machine::PortRequest)> {
            $crate::forward_bus_link!(@to self, $to).poll_port_request()
        }
    };
    (@one handle_timeout, $to:tt, [$($hook:ident)?]) => {
        fn handle_timeout(&mut self, now: $crate::Instant) {
            $(self.$hook(now);)?
            $crate::forward_bus_link!(@to self, $to).handle_timeout(now);
        }
    };
    (@one poll_timeout, $to:tt, [$($hook:ident)?]) => {
        fn poll_timeout(&self) -> Option<$crate::Instant> {
            $crate::forward_bus_link!(@to self, $to).poll_timeout()
        }
    };
    (@one poll_event, $to:tt, [$($hook:ident)?]) => {
        fn poll_event(&mut self) -> Option<Self::Event> {
            $crate::forward_bus_link!(@to self, $to).poll_event()
        }
    };
    (@one poll_machine_request, $to:tt, [$($hook:ident)?]) => {
        fn poll_machine_request(&mut self) -> Option<$crate::machine::LinkRequest> {
            $crate::forward_bus_link!(@to self, $to).poll_machine_request()
        }
    };
    (@one fd, $to:tt, [$($hook:ident)?]) => {
        #[cfg(feature = "fd")]
        fn fd_capable(&self) -> bool {
            $crate::machine::BusLink::fd_capable(&$crate::forward_bus_link!(@to self, $to))
        }
        #[cfg(feature = "fd")]
        fn handle_rx_fd(
            &mut self,
            now: $crate::Instant,
            port: usize,
            frame: &$crate::frame::FdFrame,
            at: $crate::Instant,
        ) -> Option<$crate::frame::FdFrame> {
            $(self.$hook(now);)?
            $crate::machine::BusLink::handle_rx_fd(
                &mut $crate::forward_bus_link!(@to self, $to),
                now,
                port,
                frame,
                at,
            )
        }
        #[cfg(feature = "fd")]
        fn send_fd(&mut self, now: $crate::Instant, frame: &$crate::frame::FdFrame) {
            $(self.$hook(now);)?
            $crate::machine::BusLink::send_fd(&mut $crate::forward_bus_link!(@to self, $to), now, frame);
        }
        #[cfg(feature = "fd")]
        fn poll_transmit_fd(&mut self) -> Option<(usize, $crate::frame::FdFrame)> {
            $crate::machine::BusLink::poll_transmit_fd(&mut $crate::forward_bus_link!(@to self, $to))
        }
    };
}

/// A device behind a pointer is a device: the methods are the pointee's.
macro_rules! forward_device {
    ($($ptr:tt)*) => {
        impl<D: Device + ?Sized> Device for $($ptr)* {
            type Event = D::Event;
            $crate::forward_device_to!(*);
            fn poll_event(&mut self) -> Option<D::Event> {
                (**self).poll_event()
            }
            // Here rather than in `forward_device_to!`, which expands in other crates: there
            // `feature = "fd"` would be theirs, not this crate's.
            #[cfg(feature = "fd")]
            fn fd_capable(&self) -> bool {
                (**self).fd_capable()
            }
            #[cfg(feature = "fd")]
            fn handle_rx_fd(
                &mut self,
                now: $crate::Instant,
                port: usize,
                frame: &$crate::frame::FdFrame,
                at: $crate::Instant,
            ) {
                (**self).handle_rx_fd(now, port, frame, at);
            }
            #[cfg(feature = "fd")]
            fn poll_transmit_fd(&mut self) -> Option<(usize, $crate::frame::FdFrame)> {
                (**self).poll_transmit_fd()
            }
        }
    };
}

// A boxed device is a device: large machines (a redundant master) live on the heap, and a
// simulator or runtime that owns devices by value can own the box.
#[cfg(feature = "alloc")]
forward_device!(alloc::boxed::Box<D>);

// A borrowed device is a device: on a microcontroller a large one (a redundant master's
// station, tens of kilobytes) lives in a `static` built in place, and the driver borrows it
// for good (`&'static mut`) rather than having it copied through the stack into itself.
forward_device!(&mut D);
