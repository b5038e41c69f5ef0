"""The daemon: supervised services in one asyncio process."""
