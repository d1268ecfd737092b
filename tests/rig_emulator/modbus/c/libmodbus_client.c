/* A Modbus TCP client built on libmodbus (Debian libmodbus-dev), compiled by
 * tests/rig_emulator/modbus/test_libmodbus.py. Usage: libmodbus_client HOST PORT
 * Prints one "key=value" line per check; exit 0 when every call behaved as libmodbus
 * documents, 1 otherwise (the line says which). */
#include <errno.h>
#include <modbus.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures = 0;

static void fail(const char *what) {
    printf("error=%s: %s\n", what, modbus_strerror(errno));
    failures++;
}

/* float32 in two registers, high word first (ABCD). Written out here: the _abcd helpers
 * of Debian 12's libmodbus 3.1.6 did not round-trip 512.5 through the server in this test. */
static void set_float_abcd(float value, uint16_t *regs) {
    uint32_t bits;
    memcpy(&bits, &value, sizeof bits);
    regs[0] = (uint16_t)(bits >> 16);
    regs[1] = (uint16_t)(bits & 0xFFFF);
}

static float get_float_abcd(const uint16_t *regs) {
    uint32_t bits = ((uint32_t)regs[0] << 16) | regs[1];
    float value;
    memcpy(&value, &bits, sizeof value);
    return value;
}

/* the error libmodbus reports for a Modbus exception, by name */
static const char *exception_name(int err) {
    switch (err) {
    case EMBXILFUN: return "illegal_function";
    case EMBXILADD: return "illegal_data_address";
    case EMBXILVAL: return "illegal_data_value";
    case EMBXSFAIL: return "server_failure";
    case EMBXGTAR: return "gateway_target";
    default: return "other";
    }
}

/* send a raw request PDU for unit 1 and print the reply's function and exception bytes */
static void raw_exception(modbus_t *ctx, const char *key, const uint8_t *req, int len) {
    uint8_t rsp[MODBUS_TCP_MAX_ADU_LENGTH];
    if (modbus_send_raw_request(ctx, req, len) == -1) {
        fail(key);
        return;
    }
    int n = modbus_receive_confirmation(ctx, rsp);
    if (n < 9) {
        fail(key);
        return;
    }
    printf("%s=%02x%02x\n", key, rsp[7], rsp[8]); /* after the 7-byte MBAP header */
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s HOST PORT\n", argv[0]);
        return 2;
    }
    modbus_t *ctx = modbus_new_tcp(argv[1], atoi(argv[2]));
    if (ctx == NULL || modbus_connect(ctx) == -1) {
        fail("connect");
        return 1;
    }
    modbus_set_response_timeout(ctx, 10, 0);
    uint16_t regs[MODBUS_MAX_READ_REGISTERS];
    uint8_t bits[8];

    /* unit 1, bench PLC: 14 input registers; flow setpoint (holding 0-1, float ABCD) */
    modbus_set_slave(ctx, 1);
    if (modbus_read_input_registers(ctx, 0, 14, regs) != 14) fail("read_input_registers");
    else printf("water_flow_kg_h=%.6g\n", get_float_abcd(regs));
    set_float_abcd(512.5f, regs);
    if (modbus_write_registers(ctx, 0, 2, regs) != 2) fail("write_registers");
    if (modbus_read_registers(ctx, 0, 2, regs) != 2) fail("read_registers");
    else printf("flow_setpoint_kg_h=%.6g\n", get_float_abcd(regs));
    uint16_t wr[2], rd[2];
    set_float_abcd(55.5f, wr);
    if (modbus_write_and_read_registers(ctx, 2, 2, wr, 2, 2, rd) != 2) fail("write_and_read");
    else printf("return_setpoint_C=%.6g\n", get_float_abcd(rd));

    /* unit 7, boiler controller: coil 0 is the on command */
    modbus_set_slave(ctx, 7);
    if (modbus_write_bit(ctx, 0, TRUE) != 1) fail("write_bit");
    if (modbus_read_bits(ctx, 0, 1, bits) != 1) fail("read_bits");
    else printf("on_command=%d\n", bits[0]);

    /* expected exceptions, as libmodbus reports them */
    modbus_set_slave(ctx, 1);
    if (modbus_read_input_registers(ctx, 30, 2, regs) != -1) fail("unmapped read answered");
    else printf("unmapped_read=%s\n", exception_name(errno));
    uint8_t id[64];
    if (modbus_report_slave_id(ctx, sizeof id, id) != -1) fail("report_slave_id answered");
    else printf("report_slave_id=%s\n", exception_name(errno));
    modbus_set_slave(ctx, 42);
    if (modbus_read_input_registers(ctx, 0, 2, regs) != -1) fail("unknown unit answered");
    else printf("unknown_unit=%s\n", exception_name(errno));

    /* requests libmodbus's own API refuses to build: sent raw */
    modbus_set_slave(ctx, 1);
    const uint8_t coil_0x1234[] = {1, 0x05, 0x00, 0x00, 0x12, 0x34};
    raw_exception(ctx, "write_coil_0x1234", coil_0x1234, sizeof coil_0x1234);
    const uint8_t read_126[] = {1, 0x04, 0x00, 0x00, 0x00, 0x7E};
    raw_exception(ctx, "read_126_registers", read_126, sizeof read_126);

    modbus_close(ctx);
    modbus_free(ctx);
    return failures ? 1 : 0;
}
