//! Ports for tests that open network endpoints on the loopback interface.

use std::net::TcpListener;

/// `N` distinct TCP ports that were free on 127.0.0.1 a moment ago: all `N` are bound at once, so no two
/// are the same, then released for the test to listen on.
pub fn free_tcp_ports<const N: usize>() -> [u16; N] {
    let listeners: Vec<TcpListener> = (0..N)
        .map(|_| TcpListener::bind("127.0.0.1:0").expect("binding a free port on 127.0.0.1"))
        .collect();
    std::array::from_fn(|k| {
        listeners[k]
            .local_addr()
            .expect("the address of a bound listener")
            .port()
    })
}
