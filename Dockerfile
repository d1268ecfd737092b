# One image for both services: the emulator (rig-emulator serve) and the client (hil-client).
FROM python:3.11-slim
WORKDIR /app
COPY pyproject.toml README.md ./
COPY rig_emulator ./rig_emulator
COPY hil_client ./hil_client
RUN pip install --no-cache-dir -e . \
    && python -c "import rig_emulator.bench, rig_emulator.instruments"  # warm the numba cache
# Modbus/TCP (5020) and Modbus/TCP Security (802, docker-compose.tls.yml)
EXPOSE 5020 802
CMD ["rig-emulator", "--help"]
