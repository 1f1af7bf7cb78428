//! Whether an address lies in executable memory, read from the process's own memory map
//! (`/proc/self/maps`, proc(5)). The host asks it of a library's entry symbol before calling it, so an
//! entry exported as a data object (`const SkidLibraryDecl *skid_plugin_entry = …;` instead of a
//! function) is refused with a message naming the mistake rather than crashing the host.

/// `Some(true)` when `address` lies in an executable mapping, `Some(false)` when it lies in a mapping
/// that is not executable, and `None` when the memory map cannot be read (other platforms) or does not
/// hold the address.
pub(crate) fn is_executable(address: usize) -> Option<bool> {
    let maps = std::fs::read_to_string("/proc/self/maps").ok()?;
    maps.lines().find_map(|line| {
        let mut fields = line.split_whitespace();
        let (range, permissions) = (fields.next()?, fields.next()?);
        let (start, end) = range.split_once('-')?;
        let start = usize::from_str_radix(start, 16).ok()?;
        let end = usize::from_str_radix(end, 16).ok()?;
        (start..end).contains(&address).then(|| permissions.contains('x'))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    static DATA: [u64; 4] = [1, 2, 3, 4];

    fn code() -> u32 {
        7
    }

    #[test]
    fn functions_are_executable_and_data_is_not() {
        if !std::path::Path::new("/proc/self/maps").exists() {
            assert_eq!(is_executable(code as *const () as usize), None);
            return;
        }
        assert_eq!(is_executable(code as *const () as usize), Some(true));
        assert_eq!(is_executable(DATA.as_ptr() as usize), Some(false));
        assert_eq!(is_executable(0), None, "nothing is mapped at address 0");
    }
}
