//! Whose a file is: this process's user's, root's, or another user's. In a directory others
//! may write to (`/tmp`), another user can leave a file under a name tessera opens; one of
//! theirs is never resumed, written into, nor read as part of a database.

/// This process's effective user id: the user whose files it trusts and writes.
pub fn this_user() -> u32 {
    rustix::process::geteuid().as_raw()
}

/// Whether a file owned by `uid` is another user's: neither this process's user's nor
/// root's (root can write any file, so a file of root's tells nothing new), nor one of
/// `trusted` (a database's owner, for the files SQLite keeps beside it).
pub fn is_another_users(uid: u32, trusted: &[u32]) -> bool {
    uid != this_user() && uid != 0 && !trusted.contains(&uid)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_user_and_root_are_trusted_and_others_only_when_named() {
        let me = this_user();
        assert!(!is_another_users(me, &[]));
        assert!(!is_another_users(0, &[]));
        // A user id neither this one nor root's.
        let other = if me == u32::MAX - 1 {
            u32::MAX - 2
        } else {
            u32::MAX - 1
        };
        assert!(is_another_users(other, &[]));
        assert!(!is_another_users(other, &[other]));
        assert!(is_another_users(other, &[other - 1]));
    }
}
