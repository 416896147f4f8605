#!/bin/sh
# The device's USB gadget: one CDC-ACM serial function, /dev/ttyGS0 on the device,
# /dev/ttyACM0 on the host. Run as root at boot (hw/systemd/adaproj-gadget.service).
#
#   adaproj-gadget.sh start   create the gadget in configfs and bind it to the UDC
#   adaproj-gadget.sh stop    unbind and remove it
#
# Needs the board's USB port in peripheral mode (Raspberry Pi: dtoverlay=dwc2 in
# config.txt, and dwc2 loaded) and the libcomposite module. CONFIGFS can point the
# script at another tree for a dry run.
set -eu

CONFIGFS="${CONFIGFS:-/sys/kernel/config}"
G="$CONFIGFS/usb_gadget/adaproj"
VID=0x1d6b           # Linux Foundation
PID=0x0104           # Multifunction Composite Gadget
MANUFACTURER="adaproj"  # the host's udev rule matches this string
PRODUCT="adaproj pico-projector"

serial_number() {
    if [ -r /proc/device-tree/serial-number ]; then
        tr -d '\0' < /proc/device-tree/serial-number
    elif [ -r /etc/machine-id ]; then
        cut -c1-16 /etc/machine-id
    else
        echo 0000000000000000
    fi
}

start() {
    if [ -d "$G" ] && [ -n "$(cat "$G/UDC" 2>/dev/null)" ]; then
        echo "adaproj-gadget: already bound to $(cat "$G/UDC")"
        return 0
    fi
    modprobe libcomposite 2>/dev/null || true
    if ! mountpoint -q "$CONFIGFS" 2>/dev/null && [ "$CONFIGFS" = /sys/kernel/config ]; then
        mount -t configfs none "$CONFIGFS"
    fi
    mkdir -p "$G"
    echo "$VID" > "$G/idVendor"
    echo "$PID" > "$G/idProduct"
    echo 0x0100 > "$G/bcdDevice"
    echo 0x0200 > "$G/bcdUSB"
    mkdir -p "$G/strings/0x409"
    serial_number > "$G/strings/0x409/serialnumber"
    echo "$MANUFACTURER" > "$G/strings/0x409/manufacturer"
    echo "$PRODUCT" > "$G/strings/0x409/product"
    mkdir -p "$G/configs/c.1/strings/0x409"
    echo "CDC ACM (SMP content link)" > "$G/configs/c.1/strings/0x409/configuration"
    echo 250 > "$G/configs/c.1/MaxPower"
    mkdir -p "$G/functions/acm.usb0"
    [ -e "$G/configs/c.1/acm.usb0" ] || ln -s "$G/functions/acm.usb0" "$G/configs/c.1/"
    udc="$(ls /sys/class/udc 2>/dev/null | head -n 1)"
    if [ -z "$udc" ]; then
        echo "adaproj-gadget: no USB device controller in /sys/class/udc;" \
             "check dtoverlay=dwc2 and that the dwc2 module is loaded" >&2
        exit 1
    fi
    echo "$udc" > "$G/UDC"
    echo "adaproj-gadget: ACM gadget bound to $udc (/dev/ttyGS0)"
}

stop() {
    [ -d "$G" ] || return 0
    echo "" > "$G/UDC" 2>/dev/null || true
    rm -f "$G/configs/c.1/acm.usb0"
    rmdir "$G/configs/c.1/strings/0x409" "$G/configs/c.1" \
          "$G/functions/acm.usb0" "$G/strings/0x409" "$G" 2>/dev/null || true
    echo "adaproj-gadget: removed"
}

case "${1:-}" in
    start) start ;;
    stop) stop ;;
    *) echo "usage: $0 start|stop" >&2; exit 2 ;;
esac
