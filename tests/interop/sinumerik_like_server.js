// A machine-like OPC UA server built on node-opcua (an implementation independent of
// cnctwin's asyncua), laid out like a SINUMERIK 840D sl OPC UA server: string NodeIds
// "ns=2;s=/Channel/..." in the namespace "SinumerikVarProvider", the node ids of
// examples/opcua/sinumerik_840d_sl.toml. It is a test double, not a model of a real control.
//
// Usage: node sinumerik_like_server.js --port N --pki DIR [--user NAME --password SECRET]
// (DIR: where node-opcua keeps its own certificate; one folder per test session)
//
// - Anonymous sessions read; the user given (role Operator) may also write the two overrides.
// - An override write is checked (0..120 % feed, 50..120 % spindle; BadOutOfRange outside),
//   rounded to whole percent like an override switch, applied, and logged on stdout as
//   {"write": NODE, "value": APPLIED, "user": NAME}; every write is one line, so a test counts
//   the commands that reached the machine.
// - stdin takes one command per line: "garbage" publishes values a client must reject
//   (NaN load, infinite spindle speed, a negative tool number), "clean" ends that.
// - Prints {"ready": PORT} on stdout once listening.
"use strict";

const { OPCUAServer } = require("node-opcua-server");
const { OPCUACertificateManager } = require("node-opcua-certificate-manager");
const { makeRoles, WellKnownRoles, PermissionType } = require("node-opcua-address-space");
const { Variant, DataType } = require("node-opcua-variant");
const { StatusCodes } = require("node-opcua-status-code");
const readline = require("readline");

function option(name, fallback) {
    const i = process.argv.indexOf(`--${name}`);
    return i > 0 && i + 1 < process.argv.length ? process.argv[i + 1] : fallback;
}

const port = Number(option("port", "4841"));
const user = option("user", null);
const password = option("password", null);
const pki = option("pki", null);

function emit(obj) {
    process.stdout.write(JSON.stringify(obj) + "\n");
}

const state = {
    t0: Date.now(),
    feedOvr: 100.0,
    speedOvr: 100.0,
    garbage: false,
};

function elapsed() {
    return (Date.now() - state.t0) / 1000.0;
}

// The read nodes: NodeId string -> [DataType, value function]
const reads = {
    "/Channel/State/actProgNetTime": [DataType.Double, () => elapsed()],
    "/Channel/ProgramInfo/actLineNumber": [DataType.Int32, () => 10 + Math.floor(elapsed())],
    "/Channel/MachineAxis/actToolBasePos[u1,1]": [DataType.Double, () => 100 + 10 * Math.sin(elapsed())],
    "/Channel/MachineAxis/actToolBasePos[u1,2]": [DataType.Double, () => 50 + 10 * Math.cos(elapsed())],
    "/Channel/MachineAxis/actToolBasePos[u1,3]": [DataType.Double, () => -20.0],
    "/Channel/MachineAxis/aaLoad[u1,1]": [DataType.Double, () => 12.5],
    "/Channel/MachineAxis/aaLoad[u1,2]": [DataType.Double, () => (state.garbage ? NaN : 8.25)],
    "/Channel/MachineAxis/aaLoad[u1,3]": [DataType.Double, () => 20.0],
    "/Channel/State/actFeedRateIpo": [DataType.Double, () => (1200.0 * state.feedOvr) / 100.0],
    "/Channel/Spindle/actSpeed[u1,1]": [
        DataType.Double,
        () => (state.garbage ? Infinity : (8000.0 * state.speedOvr) / 100.0),
    ],
    "/Channel/Spindle/cmdSpeed[u1,1]": [DataType.Double, () => (8000.0 * state.speedOvr) / 100.0],
    "/Channel/State/actTNumber": [DataType.Int32, () => (state.garbage ? -5 : 3)],
};

// The writable overrides: NodeId string -> [state key, low %, high %]
const writes = {
    "/Channel/State/feedRateIpoOvr": ["feedOvr", 0.0, 120.0],
    "/Channel/Spindle/speedOvr[u1,1]": ["speedOvr", 50.0, 120.0],
};

const readOnly = [
    { roleId: WellKnownRoles.Anonymous, permissions: PermissionType.Browse | PermissionType.Read },
    { roleId: WellKnownRoles.Operator, permissions: PermissionType.Browse | PermissionType.Read },
];
const operatorWrites = [
    { roleId: WellKnownRoles.Anonymous, permissions: PermissionType.Browse | PermissionType.Read },
    {
        roleId: WellKnownRoles.Operator,
        permissions: PermissionType.Browse | PermissionType.Read | PermissionType.Write,
    },
];

async function main() {
    const userManager = {
        isValidUser: (name, secret) => user !== null && name === user && secret === password,
        getUserRoles: (name) =>
            name === user ? makeRoles([WellKnownRoles.AuthenticatedUser, WellKnownRoles.Operator]) : makeRoles([WellKnownRoles.Anonymous]),
    };
    const server = new OPCUAServer({
        port,
        hostname: "127.0.0.1",
        resourcePath: "/",
        userManager,
        allowAnonymous: true,
        serverCertificateManager: pki
            ? new OPCUACertificateManager({ rootFolder: pki, automaticallyAcceptUnknownCertificate: true })
            : undefined,
        // user certificates too, so that nothing is written under $HOME
        userCertificateManager: pki
            ? new OPCUACertificateManager({ rootFolder: `${pki}/users`, automaticallyAcceptUnknownCertificate: true })
            : undefined,
        buildInfo: { productName: "cnctwin interop: SINUMERIK-like test server" },
    });
    await server.initialize();
    const space = server.engine.addressSpace;
    const ns = space.registerNamespace("SinumerikVarProvider");
    if (ns.index !== 2) {
        throw new Error(`SinumerikVarProvider got namespace index ${ns.index}, expected 2`);
    }
    const folder = ns.addFolder(space.rootFolder.objects, { browseName: "Sinumerik" });
    for (const [id, [dataType, value]] of Object.entries(reads)) {
        const v = ns.addVariable({
            componentOf: folder,
            nodeId: `s=${id}`,
            browseName: id,
            dataType,
            minimumSamplingInterval: 10,
            rolePermissions: readOnly,
        });
        v.bindVariable({ get: () => new Variant({ dataType, value: value() }) }, true);
    }
    for (const [id, [key, low, high]] of Object.entries(writes)) {
        const v = ns.addVariable({
            componentOf: folder,
            nodeId: `s=${id}`,
            browseName: id,
            dataType: DataType.Double,
            accessLevel: "CurrentRead | CurrentWrite",
            userAccessLevel: "CurrentRead | CurrentWrite",
            minimumSamplingInterval: 10,
            rolePermissions: operatorWrites,
        });
        v.bindVariable(
            {
                get: () => new Variant({ dataType: DataType.Double, value: state[key] }),
                set: (variant) => {
                    const x = Number(variant.value);
                    if (typeof variant.value !== "number" || !Number.isFinite(x) || x < low || x > high) {
                        emit({ refused: id, value: String(variant.value) });
                        return StatusCodes.BadOutOfRange;
                    }
                    state[key] = Math.round(x);
                    emit({ write: id, value: state[key], user });
                    return StatusCodes.Good;
                },
            },
            true,
        );
    }
    await server.start();
    emit({ ready: port });

    const lines = readline.createInterface({ input: process.stdin });
    lines.on("line", (line) => {
        const cmd = line.trim();
        if (cmd === "garbage") state.garbage = true;
        if (cmd === "clean") state.garbage = false;
        emit({ ack: cmd });
    });
    const stop = async () => {
        await server.shutdown(0);
        process.exit(0);
    };
    process.on("SIGTERM", stop);
    process.on("SIGINT", stop);
}

main().catch((err) => {
    process.stderr.write(`sinumerik_like_server: ${err.stack || err}\n`);
    process.exit(1);
});
