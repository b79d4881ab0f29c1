//! The TCP port a child process listens on, read from Linux's /proc, so that a broker bound to
//! port 0 (a port the kernel chose and holds for it) is found without a race.

use std::collections::HashSet;

/// The socket inodes process `pid` has open (`/proc/PID/fd/N` → `socket:[INODE]`).
fn socket_inodes(pid: u32) -> HashSet<u64> {
    let Ok(fds) = std::fs::read_dir(format!("/proc/{pid}/fd")) else {
        return HashSet::new();
    };
    fds.filter_map(|fd| std::fs::read_link(fd.ok()?.path()).ok())
        .filter_map(|link| {
            let s = link.to_str()?;
            s.strip_prefix("socket:[")?.strip_suffix(']')?.parse().ok()
        })
        .collect()
}

/// The port of a listening socket in a `/proc/net/tcp{,6}` table whose inode is in `inodes`.
fn listening_port(table: &str, inodes: &HashSet<u64>) -> Option<u16> {
    const LISTEN: &str = "0A";
    table.lines().skip(1).find_map(|line| {
        let f: Vec<&str> = line.split_whitespace().collect();
        let (local, state, inode) = (f.get(1)?, f.get(3)?, f.get(9)?.parse::<u64>().ok()?);
        if *state != LISTEN || !inodes.contains(&inode) {
            return None;
        }
        u16::from_str_radix(local.rsplit(':').next()?, 16).ok()
    })
}

/// The TCP port process `pid` listens on, if it listens on one yet.
pub fn port_of(pid: u32) -> Option<u16> {
    let inodes = socket_inodes(pid);
    if inodes.is_empty() {
        return None;
    }
    ["/proc/net/tcp", "/proc/net/tcp6"]
        .iter()
        .filter_map(|t| std::fs::read_to_string(t).ok())
        .find_map(|t| listening_port(&t, &inodes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_port_of_a_listening_socket_of_this_process() {
        let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        let port = l.local_addr().expect("address").port();
        assert_eq!(port_of(std::process::id()), Some(port));
    }

    #[test]
    fn a_connected_socket_is_not_a_listening_one() {
        let table = "  sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout inode\n   \
             0: 0100007F:A3F1 0100007F:1F90 01 00000000:00000000 00:00000000 00000000     0        0 4242 1\n   \
             1: 0100007F:9C40 00000000:0000 0A 00000000:00000000 00:00000000 00000000     0        0 4243 1\n";
        assert_eq!(listening_port(table, &HashSet::from([4242])), None);
        assert_eq!(listening_port(table, &HashSet::from([4243])), Some(0x9C40));
    }
}
