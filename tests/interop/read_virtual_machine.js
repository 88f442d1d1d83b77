// A node-opcua client (independent of cnctwin's asyncua) that reads cnctwin's virtual machine
// server and prints what it found as one JSON line:
//   {"types": {PATH: TYPE_NODE_ID}, "values": {PATH: VALUE}, "datatypes": {PATH: NODE_ID},
//    "machines": [BROWSE_NAME, ...]}
// PATH is a browse path below the MachineTool object (Machine Tools namespace names), or
// "cnctwin:IDENTIFIER" for a node of cnctwin's own tree. Node ids are printed with the
// namespace URI (nsu=...), so the caller compares them with the specification's NodeIds.csv.
//
// Usage: node read_virtual_machine.js ENDPOINT PKI_DIR
"use strict";

const { OPCUAClient, AttributeIds, BrowseDirection, MessageSecurityMode, SecurityPolicy } =
    require("node-opcua-client");
const { OPCUACertificateManager } = require("node-opcua-certificate-manager");

const MT = "http://opcfoundation.org/UA/MachineTool/";
const MACHINERY = "http://opcfoundation.org/UA/Machinery/";
const CNCTWIN = "urn:cnctwin:virtual-machine";

const paths = [
    [],
    ["Identification"],
    ["Monitoring"],
    ["Monitoring", "MachineTool"],
    ["Monitoring", "Spindle"],
    ["Monitoring", "Channel1"],
    ["Production"],
    ["Production", "ActiveProgram"],
    ["Equipment"],
    ["Notification"],
];
const values = [
    ["Monitoring", "Channel1", "FeedOverride"],
    ["Monitoring", "Channel1", "ChannelState"],
    ["Monitoring", "Spindle", "Override"],
    ["Monitoring", "Spindle", "IsRotating"],
    ["Monitoring", "MachineTool", "OperationMode"],
];
const cnctwinNodes = [
    "Machine.Monitoring.Channel1.FeedOverride",
    "Machine.Monitoring.Spindle1.Override",
    "Machine.Monitoring.Spindle1.ActSpeed",
    "Machine.Monitoring.Channel1.ChannelState",
];

async function main() {
    const [endpoint, pki] = process.argv.slice(2);
    const client = OPCUAClient.create({
        endpointMustExist: false,
        securityMode: MessageSecurityMode.None,
        securityPolicy: SecurityPolicy.None,
        connectionStrategy: { maxRetry: 3, initialDelay: 200, maxDelay: 1000 },
        clientCertificateManager: new OPCUACertificateManager({
            rootFolder: pki,
            automaticallyAcceptUnknownCertificate: true,
        }),
    });
    await client.connect(endpoint);
    const session = await client.createSession();
    try {
        const uris = await session.readNamespaceArray();
        const uriOf = (index) => uris[index];
        const ns = (uri) => uris.indexOf(uri);
        const text = (nodeId) => `nsu=${uriOf(nodeId.namespace)};${nodeId.toString().replace(/^ns=\d+;/, "")}`;
        const result = { types: {}, values: {}, datatypes: {}, machines: [] };

        // the Machinery Machines folder (i=1001) holds the MachineTool object
        const machines = await session.browse({
            nodeId: `ns=${ns(MACHINERY)};i=1001`,
            browseDirection: BrowseDirection.Forward,
            resultMask: 63,
        });
        result.machines = machines.references.map((r) => r.browseName.toString());
        const root = `ns=${ns(CNCTWIN)};s=MachineTool`;

        async function resolve(path) {
            if (path.length === 0) return root;
            const browsePath = {
                startingNode: root,
                relativePath: {
                    elements: path.map((name) => ({
                        referenceTypeId: "i=33", // HierarchicalReferences
                        isInverse: false,
                        includeSubtypes: true,
                        targetName: { namespaceIndex: name === "Identification" ? ns("http://opcfoundation.org/UA/DI/") : ns(MT), name },
                    })),
                },
            };
            const found = await session.translateBrowsePath(browsePath);
            if (!found.targets || found.targets.length === 0) {
                throw new Error(`no node at ${path.join("/")}: ${found.statusCode.toString()}`);
            }
            return found.targets[0].targetId;
        }

        for (const path of paths) {
            const nodeId = await resolve(path);
            const refs = await session.browse({
                nodeId,
                referenceTypeId: "HasTypeDefinition",
                browseDirection: BrowseDirection.Forward,
                resultMask: 63,
            });
            result.types[path.join("/")] = text(refs.references[0].nodeId);
        }
        for (const path of values) {
            const nodeId = await resolve(path);
            const dv = await session.read({ nodeId, attributeId: AttributeIds.Value });
            result.values[path.join("/")] = dv.value.value;
            const dt = await session.read({ nodeId, attributeId: AttributeIds.DataType });
            result.datatypes[path.join("/")] = text(dt.value.value);
        }
        for (const id of cnctwinNodes) {
            const nodeId = `ns=${ns(CNCTWIN)};s=${id}`;
            const dv = await session.read({ nodeId, attributeId: AttributeIds.Value });
            result.values[`cnctwin:${id}`] = dv.value.value;
            const dt = await session.read({ nodeId, attributeId: AttributeIds.DataType });
            result.datatypes[`cnctwin:${id}`] = text(dt.value.value);
        }
        process.stdout.write(JSON.stringify(result) + "\n");
    } finally {
        await session.close();
        await client.disconnect();
    }
}

main().catch((err) => {
    process.stderr.write(`read_virtual_machine: ${err.stack || err}\n`);
    process.exit(1);
});
