// villas_calls: every RTAPI call VILLASnode's Orchestra node (lib/nodes/opal_orchestra.cpp)
// makes, in its order and with the argument types it declares (unsigned int connection key
// and timeout, unsigned int * status, unsigned short item keys and lengths, unsigned int type
// sizes, char * buffers reached through (void **), bool flags), including
// RTSetupRefMemRemoteConnection for a domain whose DDF connection is remote. Compiled with
// -Wall -Wextra -Wconversion -Werror by the test suite.
//
//   villas_calls DDF DOMAIN STEPS [CARD PCI_INDEX]
//
// Each step it reads the float64 PUBLISH item x and answers y = 2 x. Prints "x=V" per step.
extern "C" {
#include <RTAPI.h>
}

#include <cstdio>
#include <cstdlib>
#include <string>

namespace {

struct Mapping {
    std::string path;
    unsigned short key;
    char *buffer;
    unsigned int typeSize; // sizeof() of the signal type
    unsigned short length;
};

bool ok(RTAPIReturn_t ret, const char *what)
{
    if (ret != RTAPI_SUCCESS) {
        std::fprintf(stderr, "villas_calls: %s: %s (%d): %s\n", what, RTGetErrorMessage(ret), static_cast<int>(ret),
                     RTGetLastErrorDetail());
        return false;
    }
    return true;
}

bool prepare(unsigned int connectionKey, Mapping &m)
{
    return ok(RTGetInfoForItem(m.path.c_str(), &m.typeSize, &m.length), "RTGetInfoForItem")
        && ok(RTGetKeyForItem(m.path.c_str(), &m.key), "RTGetKeyForItem")
        && ok(RTGetBuffer(connectionKey, m.key, reinterpret_cast<void **>(&m.buffer)), "RTGetBuffer");
}

} // namespace

int main(int argc, char **argv)
{
    if (argc < 4) {
        std::fprintf(stderr, "usage: %s DDF DOMAIN STEPS [CARD PCI_INDEX]\n", argv[0]);
        return 2;
    }
    const std::string ddf = argv[1], domain = argv[2];
    const long steps = std::atol(argv[3]);
    const bool remote = argc >= 6;
    const std::string card = remote ? argv[4] : "";
    const int pciIndex = remote ? std::atoi(argv[5]) : 0;

    unsigned int connectionKey;
    unsigned int *status;
    unsigned int connectTimeout = 30; // in seconds, as VILLASnode keeps it
    unsigned int flagDelay = 100;     // microseconds
    bool useFlagWithTool = false;
    bool skipWaitToGo = false;

    if (!ok(RTNewConnectionKey(&connectionKey), "RTNewConnectionKey")
        || !ok(RTSetConnectionKey(connectionKey), "RTSetConnectionKey")
        || !ok(RTConnectWithFile(ddf.c_str(), domain.c_str(), static_cast<int>(connectTimeout)), "RTConnectWithFile")
        || !ok(RTGetConnectionStatusPtr(connectionKey, &status), "RTGetConnectionStatusPtr")
        || !ok(RTDefineFlagDelay(flagDelay), "RTDefineFlagDelay")
        || !ok(RTUseFlagWithTool(useFlagWithTool ? flagDelay : 0u), "RTUseFlagWithTool")
        || !ok(RTDefineFlagDelay(flagDelay), "RTDefineFlagDelay")
        || !ok(RTSetSkipWaitToGoAtConnection(skipWaitToGo), "RTSetSkipWaitToGoAtConnection")) {
        return 1;
    }
    if (remote && !ok(RTSetupRefMemRemoteConnection(card.c_str(), pciIndex), "RTSetupRefMemRemoteConnection")) {
        return 1;
    }
    Mapping in{"x", 0, nullptr, 0, 0}, out{"y", 0, nullptr, 0, 0};
    if (!prepare(connectionKey, in) || !prepare(connectionKey, out)) {
        return 1;
    }
    if (in.typeSize != sizeof(double) || in.length != 1 || out.typeSize != sizeof(double) || out.length != 1) {
        std::fprintf(stderr, "villas_calls: x and y must be float64 scalars\n");
        return 1;
    }
    char *bufferPublish, *bufferSubscribe;
    unsigned int bufferPublishSize, bufferSubscribeSize;
    if (!ok(RTGetBufferInfo(connectionKey, &bufferPublish, &bufferPublishSize, &bufferSubscribe, &bufferSubscribeSize),
            "RTGetBufferInfo")
        || !ok(RTWaitReadyToGo(), "RTWaitReadyToGo")) {
        return 1;
    }
    for (long i = 0; i < steps; i++) {
        double x;
        if (!ok(RTSetConnectionKey(connectionKey), "RTSetConnectionKey") || !ok(RTSubscribeLock(), "RTSubscribeLock")) {
            return 1;
        }
        x = *reinterpret_cast<double *>(in.buffer);
        RTSubscribeUnlock();
        if (!ok(RTPublishLock(), "RTPublishLock")) {
            return 1;
        }
        *reinterpret_cast<double *>(out.buffer) = 2 * x;
        RTPublishUnlock();
        std::printf("x=%.17g status=%u\n", x, *status);
    }
    return ok(RTDisconnect(), "RTDisconnect") ? 0 : 1;
}
