"""Four-motor closed-loop flight: MSP link, controller, blimp simulator."""
