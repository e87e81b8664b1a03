//! Answers of a slave to a scripted master's request (`pbcard::testkit::ScriptedMaster`),
//! classified the way the DP-V1 tests compare them: nothing, a short acknowledge, an SD1
//! answer without data (its FC), or a data answer's PDU — checked to come from the addressed
//! station to the requester with the request's SAPs swapped (reference §2.2, §3.1).

use pbcard::fdl::telegram::{decode, Decoded, Telegram};

/// One answer.
#[derive(Debug, PartialEq)]
pub enum Ans {
    /// No answer.
    None,
    /// Short acknowledge (SC).
    Sc,
    /// A telegram without data and SAPs: its function code.
    Sd1(u8),
    /// A data telegram: its PDU.
    Pdu(Vec<u8>),
}

impl Ans {
    /// The answer `resp` to `request` (a telegram the master sent). With `fc`, a data
    /// answer must carry that function code. Panics on an answer that is no valid telegram,
    /// is not addressed back to the requester, or does not swap the SAPs.
    pub fn of(request: &[u8], resp: Option<&[u8]>, fc: Option<u8>) -> Ans {
        let Some(r) = resp else { return Ans::None };
        let Decoded::Frame(Telegram::Data(req), _) = decode(request) else {
            panic!("request {request:02x?} is no data telegram")
        };
        match decode(r) {
            Decoded::Frame(Telegram::ShortAck, 1) => Ans::Sc,
            Decoded::Frame(Telegram::Data(t), _) if t.pdu.is_empty() && t.dsap.is_none() => Ans::Sd1(t.fc.0),
            Decoded::Frame(Telegram::Data(t), _) => {
                assert_eq!((t.da, t.sa), (req.sa, req.da), "answer {r:02x?} not back to the requester");
                if let Some(fc) = fc {
                    assert_eq!(t.fc.0, fc, "answer {r:02x?}");
                }
                assert_eq!((t.dsap, t.ssap), (req.ssap, req.dsap), "SAPs swapped");
                Ans::Pdu(t.pdu.to_vec())
            }
            other => panic!("invalid answer {other:?}"),
        }
    }
}
