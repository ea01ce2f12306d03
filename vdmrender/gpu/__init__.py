"""The GL device: the headless EGL context and its programs (`gl`), and which device it is, its GL strings
and its NVML clocks (`device`). Everything that draws goes through here."""
