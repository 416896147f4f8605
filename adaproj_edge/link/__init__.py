"""The serial link: SMP (MCUmgr) server, the adaproj command group, the content store."""
