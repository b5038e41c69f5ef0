"""The headset link: the aiohttp API and the browser client."""
